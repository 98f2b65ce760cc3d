"""Finite numbers that still cannot be right: a pose of 1e308 m, files on two clocks.

The readers (`ekfslam.logs.runjson`, `ekfslam.logs.runlog`, `ekfslam.logs.mrclam.load`,
`ekfslam.logs.rosbag`) and `ekfslam.pipeline` share these rules, which ``data/README.md`` states
("What the reader rejects"). A value that passes every per-cell check (finite, the right type) can
still make a replay silently wrong: a start of 1e308 m overflows to NaN, detections stamped in
nanoseconds beside controls in seconds never meet the robot's motion.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ekfslam.errors import InputError

#: |x|, |y| in metres beyond which a position is a mistake (10,000 km: UTM northings fit).
MAX_POSITION = 1e7
#: |θ| in radians beyond which a heading is a mistake (degrees, or a sum never wrapped).
MAX_HEADING = 2 * math.pi
#: Other files may reach this far outside the controls' time span: max(1 s, 10 % of the span).
SPAN_MARGIN_S, SPAN_MARGIN_FRACTION = 1.0, 0.1


def implausible_pose(values: ArrayLike, what: str, pose: bool = True) -> str | None:
    """Why finite `values` (x, y[, θ]) cannot be a place in m (and a heading in rad), or None."""
    v = np.asarray(values, dtype=np.float64)
    if np.any(np.abs(v[:2]) > MAX_POSITION):
        return f"{what}: a position beyond {MAX_POSITION:g} m is not plausible, got {v[:2]}"
    if pose and abs(v[2]) > MAX_HEADING:
        return (
            f"{what}: heading {float(v[2])!r} rad is beyond ±2π (degrees by mistake?); "
            "give the heading in radians"
        )
    return None


def check_clocks(
    controls: tuple[str, ArrayLike],
    others: Sequence[tuple[str | os.PathLike, ArrayLike, bool]],
    lines: bool = True,
) -> None:
    """Raise `InputError` unless every file in `others` shares the controls' clock.

    controls : (its file name for messages, its times (N,) in s, sorted).
    others : (path, times (M,) s sorted, covers) per file; covers: the file must also span at
        least half of the controls' time (ground truth), not only lie within it.
    lines : whether row i of a file is its line i + 2 (False: sorted, filtered, or found in
        camera frames), for the message.

    With the controls spanning [c0, c1] and m = max(1 s, 10 % of c1 - c0): every time lies in
    [c0 - m, c1 + m], at least half of each file's own span lies inside [c0, c1], and a file
    that covers spans at least half of [c0, c1].
    """
    c_name, c = controls[0], np.asarray(controls[1], dtype=float)
    c0, c1 = float(c[0]), float(c[-1])
    margin = max(SPAN_MARGIN_S, SPAN_MARGIN_FRACTION * (c1 - c0))
    for path, times, covers in others:
        t = np.asarray(times, dtype=float)
        if not len(t):
            continue
        t0, t1 = float(t[0]), float(t[-1])
        outside = np.flatnonzero((t < c0 - margin) | (t > c1 + margin))
        inside = max(0.0, min(t1, c1) - max(t0, c0))
        if outside.size:
            problem = f"time {float(t[outside[0]])!r} s is more than {margin:.3g} s outside"
            line = int(outside[0]) + 2 if lines else None
        elif t1 > t0 and inside < 0.5 * (t1 - t0):
            problem, line = "less than half of its time span overlaps", None
        elif covers and c1 > c0 and inside < 0.5 * (c1 - c0):
            problem, line = "it covers less than half of", None
        else:
            continue
        raise InputError(
            path,
            line,
            f"{problem} {c_name}'s time span: {Path(path).name} spans {t0:.3f} to {t1:.3f} s, "
            f"{c_name} {c0:.3f} to {c1:.3f} s (are the files on different clocks, "
            "such as nanoseconds and seconds?)",
        )
