"""Two commands on runs logged as camera frames: ``render-frames`` and ``detect``.

``render-frames RUN --out DIR`` renders a simulated run's camera frames (a run of frames, no
detections); ``detect RUN [--out DIR|FILE.csv | --in-place]`` finds the AprilTags in them.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ekfslam.cli import args as ca
from ekfslam.errors import InputError
from ekfslam.logs.runlog import DETECTIONS_CSV, read_run, write_detections
from ekfslam.vision.detect import VisionConfig
from ekfslam.vision.frames_run import detect_run, with_camera, write_frames_run
from ekfslam.vision.render import RenderConfig


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``render-frames`` or ``detect`` (`help`: its line in `ekfslam.cli.main`)."""
    {"render-frames": _add_render_frames, "detect": _add_detect}[name](subparsers, name, help)


def _add_render_frames(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    p = subparsers.add_parser(name, help=help)
    p.add_argument(
        "run", type=ca.given_path, help="a run folder with ground truth (e.g. from simulate)"
    )
    ca.add_run_folder_arguments(p)
    p.add_argument("--name", type=ca.non_empty, help="the new run's name (default: the run's)")
    p.add_argument(
        "--mounting",
        type=ca.finite(),
        nargs=3,
        metavar=("X", "Y", "YAW"),
        help="camera position (m, within ±0.5) and yaw (rad, within ±π) in the robot frame "
        "(default: the run's)",
    )
    p.add_check(ca.triple_check("--mounting", (0.5, 0.5, math.pi), ("X", "Y", "YAW")))
    p.add_argument("--images", action="store_true", help="PNG images instead of an mp4v video")
    p.add_argument("--keep-detections", action="store_true", help="write detections.csv too")
    p.add_argument("--seed", type=ca.seed(), default=0, help="texture and sensor-noise seed")
    p.set_defaults(func=cmd_render_frames)


def _detect_out(text: str) -> Path:
    """``detect --out``: a FILE.csv to write, or a new run folder."""
    if Path(text).suffix.lower() == ".csv":
        return ca.output_file((".csv",))(text)
    return ca.output_folder(text)


def _add_detect(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    p = subparsers.add_parser(name, help=help)
    p.add_argument(
        "run", type=ca.given_path, help="a run folder with frames (run.json, frames.csv, ...)"
    )
    p.add_argument(
        "--out",
        type=_detect_out,
        metavar="DIR|FILE.csv",
        help="a new run folder (the run copied, with detections.csv) or a FILE.csv to write; "
        "missing folders are created",
    )
    p.add_argument(
        "--in-place",
        action="store_true",
        help="write RUN/detections.csv instead; `run RUN` then uses it, not the frames",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing file")
    p.add_argument("--detector", choices=["opencv", "opencv-subpix", "apriltag"], default="opencv")
    p.add_argument(
        "--max-incidence",
        type=ca.real(0.0, 90.0, lo_open=True),
        default=75.0,
        help="refuse tags seen more edge-on than this, degrees in (0, 90] (default: %(default)s)",
    )
    p.set_defaults(func=cmd_detect)


def cmd_render_frames(args: argparse.Namespace) -> int:
    source = read_run(args.run)
    if source.groundtruth is None:
        raise InputError(
            args.run,
            None,
            "has no ground truth (groundtruth.csv): render-frames draws what the camera saw "
            "from the true poses (a simulated run has them: python -m ekfslam simulate)",
        )
    kind = "images" if args.images else "video"
    run = with_camera(source, mounting=args.mounting, kind=kind, name=args.name)
    index = write_frames_run(
        run, args.out, render=RenderConfig(seed=args.seed), overwrite=args.overwrite
    )
    if args.keep_detections:
        write_detections(source.detections, args.out / DETECTIONS_CSV, run.meta.tag_map)
    size = sum(f.stat().st_size for f in args.out.rglob("*") if f.is_file())
    print(f"wrote {args.out}: {len(index.t)} frames, {size / 1e6:.1f} MB")
    return 0


def cmd_detect(args: argparse.Namespace) -> int:
    config = VisionConfig(detector=args.detector, max_incidence=math.radians(args.max_incidence))
    path, counts = detect_run(
        args.run, args.out, config, overwrite=args.overwrite, in_place=args.in_place
    )
    c = counts.as_dict()
    refused = ", ".join(f"{k.removeprefix('refused_')} {v}" for k, v in c.items() if "refused" in k)
    print(
        f"wrote {path}: {c['accepted']} detections from {c['frames']} frames "
        f"({c['found']} tags found; refused: {refused})"
    )
    return 0
