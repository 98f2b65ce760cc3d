"""``--animate FILE [--fps F] [--frames N]``: a replay written as a movie (`ekfslam.viz.animation`).

The options are checked while parsing, before the replay, like every writing option
(`ekfslam.cli.args`): the path and its format, and for an MP4 that an ffmpeg is there. matplotlib
is imported only to write the animation, so a command that does not animate starts as fast.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import shutil
from pathlib import Path

from ekfslam.analysis.laps import lap_times
from ekfslam.cli import args as ca
from ekfslam.cli.common import arena_half_size
from ekfslam.errors import EkfSlamError
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import ReplayResult

#: What ``--animate`` writes: a GIF (Pillow, always there) or an MP4 (ffmpeg, see `has_ffmpeg`).
ANIMATION_FORMATS: tuple[str, ...] = (".gif", ".mp4")
#: ``--frames``' bound: each frame keeps a copy of the state's covariance until it is drawn.
MAX_FRAMES = 1000
#: ``--frames`` and ``--fps`` when not given: six seconds of animation.
DEFAULT_FRAMES, DEFAULT_FPS = 60, 10.0


def has_ffmpeg() -> bool:
    """Whether an MP4 can be written: ffmpeg on PATH, or the imageio-ffmpeg wheel's own binary."""
    on_path = shutil.which("ffmpeg") is not None
    return on_path or importlib.util.find_spec("imageio_ffmpeg") is not None


def add_animate_arguments(p: ca.Parser) -> None:
    """``--animate FILE --fps F --frames N``: checked before the work, like ``--plot``."""
    listed = ", ".join(ANIMATION_FORMATS)
    p.add_argument(
        "--animate",
        type=ca.output_file(ANIMATION_FORMATS),
        metavar="FILE",
        help=f"write an animation of the replay to FILE ({listed}: GIF through Pillow, MP4 "
        "through ffmpeg, found on PATH or from `pip install imageio-ffmpeg`)",
    )
    p.add_argument(
        "--fps",
        type=ca.real(1.0, 60.0, why="what a player shows"),
        metavar="F",
        help=f"--animate's frames per second (default {DEFAULT_FPS:g})",
    )
    p.add_argument(
        "--frames",
        type=ca.whole(2, MAX_FRAMES, why="each frame keeps a copy of Σ"),
        metavar="N",
        help="--animate's number of frames, spread evenly over the detections (default "
        f"{DEFAULT_FRAMES})",
    )

    def check(args: argparse.Namespace) -> str | None:
        if args.animate is None:
            options = (("--fps", args.fps), ("--frames", args.frames))
            given = [o for o, v in options if v is not None]
            return f"argument {given[0]}: only with --animate FILE" if given else None
        if args.animate.suffix.lower() == ".mp4" and not has_ffmpeg():
            return (
                "argument --animate: writing .mp4 needs ffmpeg: pip install imageio-ffmpeg "
                "(or install ffmpeg), or write a .gif"
            )
        return None

    p.add_check(check)


def write_animation(
    run: RunLog,
    result: ReplayResult,
    path: Path,
    fps: float | None,
    labels: list[str] | None = None,
) -> tuple[str, int]:
    """Write the replay's animation to `path`; returns (the path written, its frame count).

    result : a replay with keyframes (``replay(run, keyframes=...)``).
    labels : one per landmark slot (`ReplayFrames`' ``landmark_labels``), None for their ids.
    """
    animation = importlib.import_module("ekfslam.viz.animation")  # matplotlib: only when asked
    try:
        laps = lap_times(run)
    except EkfSlamError:  # not a simulated run: no laps to name
        laps = ()
    frames = animation.ReplayFrames(
        run,
        result,
        arena_half_size=arena_half_size(run),
        lap_ends=laps,
        landmark_labels=labels,
        dpi=FILE_DPI,
    )
    return str(animation.save_animation(frames, path, fps or DEFAULT_FPS)), len(frames)


#: a file's animation is drawn at 80 dpi (1120 px wide): a GIF of every frame at the notebook's
#: projector width would be four times the size and time
FILE_DPI = 80


def true_labels(result: ReplayResult, mapping: dict[int, int]) -> list[str]:
    """Each landmark slot's true id: with hidden ids the filter names its landmarks 0, 1, ..."""
    assert result.keyframes is not None  # asked for with --animate
    return [str(mapping[e]) if e in mapping else f"new {e}" for e in result.keyframes.landmark_ids]
