"""``python -m studies vision-eval [--poses N] [--seed S] [--detector D] [--run RUN] [--json]``."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math

import numpy as np

from ekfslam.analysis.vision_eval import TARGETS, VisionEvaluation, evaluate_vision
from ekfslam.cli import args as ca
from ekfslam.vision.detect import VisionConfig
from ekfslam.vision.render import RenderConfig
from studies.vision_eval import ReplayComparison, compare_replays, format_evaluation

#: Command-line limits: poses each render a 640x480 frame (about 0.1 s); a blur wider than
#: this smears a tag's 1-2 px quiet zone into its neighbours.
MAX_POSES = 100_000
MAX_BLUR = 20.0


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``vision-eval`` (`help` is the one line of `studies.__main__.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help)
    p.add_argument(
        "--poses",
        type=ca.whole(1, MAX_POSES, why="each pose renders a frame"),
        default=200,
        help="random poses (default: %(default)s)",
    )
    p.add_argument("--seed", type=ca.seed(), default=0)
    p.add_argument("--detector", choices=["opencv", "opencv-subpix", "apriltag"], default="opencv")
    p.add_argument("--no-refine", action="store_true", help="keep the detector's own corners")
    p.add_argument(
        "--blur",
        type=ca.non_negative(MAX_BLUR, why="px; the tags would vanish"),
        help="lens blur sigma, px (default: RenderConfig's)",
    )
    p.add_argument(
        "--run", type=ca.input_path, help="also compare replays of this simulated frames run"
    )
    ca.add_json_argument(p)
    p.set_defaults(func=cmd_vision_eval)


def cmd_vision_eval(args: argparse.Namespace) -> int:
    config = VisionConfig(detector=args.detector, refine=not args.no_refine)
    render = RenderConfig() if args.blur is None else RenderConfig(blur_sigma=args.blur)
    ev = evaluate_vision(args.poses, args.seed, render=render, config=config)
    if args.json:
        c = compare_replays(args.run, config) if args.run is not None else None
        print(json.dumps(_as_dict(ev, c), indent=2, allow_nan=False))
        return 0
    print(format_evaluation(ev))  # before the replays, which take a while
    if args.run is not None:
        c = compare_replays(args.run, config)
        target = TARGETS["replay_ratio"]
        print(
            f"replay of {c.name}, map error (eq. 17): {1e3 * c.frames_error:.1f} mm from its "
            f"frames ({c.frames_detections} sightings); {1e3 * c.same_sightings_error:.1f} mm from "
            f"exact range and bearing at the same sightings; {1e3 * c.exact_error:.1f} mm from the "
            f"simulator's exact detections ({c.exact_detections} sightings, "
            f"{c.common_detections} of them in the frames' too); "
            f"{1e3 * c.noisy_error:.1f} mm from its noisy ones\n"
            f"ratio frames / simulator's exact {c.ratio:.3f} (target <= {target}: "
            f"{'yes' if c.ratio <= target else 'NO'}); frames / exact at the same sightings "
            f"{c.vision_ratio:.3f}"
        )
    return 0


def _finite_or_none(value: float) -> float | None:
    """JSON has no NaN: a band without detections has no statistics."""
    return value if math.isfinite(value) else None


def _as_dict(ev: VisionEvaluation, c: ReplayComparison | None) -> dict:
    """The figures `format_evaluation` prints, as one JSON object (m, rad, ms)."""
    out = {
        "poses": ev.poses,
        "in_view": ev.in_view,
        "detected": ev.detected,
        "detection_rate": _finite_or_none(ev.detection_rate),
        "wrong_ids": ev.wrong_ids,
        "bands": [
            {
                k: _finite_or_none(v) if isinstance(v, float) else v
                for k, v in dataclasses.asdict(b).items()
            }
            for b in ev.bands()
        ],
        "bearing_std_rad": _finite_or_none(float(np.std(ev.bearing_error))),
        "frame_ms_median": _finite_or_none(float(np.median(ev.frame_ms))),
        "targets": ev.targets(),
        "counts": ev.counts.as_dict(),
    }
    if c is not None:
        out["replay"] = {
            "name": c.name,
            "frames_error": c.frames_error,
            "same_sightings_error": c.same_sightings_error,
            "exact_error": c.exact_error,
            "noisy_error": c.noisy_error,
            "frames_detections": c.frames_detections,
            "exact_detections": c.exact_detections,
            "common_detections": c.common_detections,
            "ratio": c.ratio,
            "vision_ratio": c.vision_ratio,
            "target_ratio": TARGETS["replay_ratio"],
        }
    return out
