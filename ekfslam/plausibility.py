"""Finite numbers that still cannot be right: a pose of 1e308 m, files on two clocks.

The readers (`ekfslam.logs.runjson`, `ekfslam.logs.runlog`, `ekfslam.logs.mrclam.load`,
`ekfslam.logs.rosbag`) and `ekfslam.pipeline` share these rules, which ``data/README.md`` states
("What the reader rejects"). A value that passes every per-cell check (finite, the right type) can
still make a replay silently wrong: a start of 1e308 m overflows to NaN, detections stamped in
nanoseconds beside controls in seconds never meet the robot's motion.

Across a file and across files (issue 27), each a decision, refused with the file and the line:

- a value beyond what any robot measures (`MAX_TIME`, `MAX_SPEED`, `MAX_TURN_RATE`,
  `MAX_WHEEL_SPEED`, `MAX_POSITION` for ranges and positions): a wheel speed of 1e300 rad/s is a
  corrupt cell, and would otherwise end as a non-finite filter state naming neither file nor line;
- a hole in the controls while the robot moves (`control_hole`): the replay holds the last
  control, so an hour without rows drives the robot on blind for an hour;
- a ground-truth heading beyond ±2π (degrees, or never wrapped), as for ``nominal_start``;
- a tag map whose tags all lie at one point: eq. (17) cannot find a rotation from it
  (`coincident`; two tags at one point are warned about);
- ranges, true positions or a start too far from the tag map to belong to it
  (`beyond_map`: millimetres for metres, or another map's file);
- time that goes back in a recorded log by more than `BACKWARDS_TOLERANCE_S` (two logs pasted
  together: another robot's measurements appended); less is sorted, counted and warned about;
- sightings that do not fit the true poses (`sightings_off_truth`): with ground truth and a tag
  map, more than `OFF_TRUTH_FRACTION` of the sightings off by more than `OFF_TRUTH_BEARING` rad
  or `OFF_TRUTH_RANGE` m (MRCLAM's own: at most 0.15 %): another robot's measurements merged in
  time order, or a map in another frame.
"""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ekfslam.errors import InputError
from ekfslam.geometry import wrap_angle

#: |x|, |y| in metres beyond which a position is a mistake (10,000 km: UTM northings fit).
MAX_POSITION = 1e7
#: |θ| in radians beyond which a heading is a mistake (degrees, or a sum never wrapped).
MAX_HEADING = 2 * math.pi
#: Other files may reach this far outside the controls' time span: max(1 s, 10 % of the span).
SPAN_MARGIN_S, SPAN_MARGIN_FRACTION = 1.0, 0.1
#: |t| in s beyond which a time is a mistake: 3,000 years of Unix time (ns stamps are 1.7e18).
MAX_TIME = 1e11
#: |v| in m/s, |ω| in rad/s and wheel speeds in rad/s beyond which a control is a corrupt cell.
MAX_SPEED, MAX_TURN_RATE, MAX_WHEEL_SPEED = 1e3, 1e3, 1e4
#: A gap between control rows longer than this many s, and this many times the usual one, while
#: the held control moves the robot, is a hole (MRCLAM's longest is 1.4 s, ours 0.05 s).
HOLE_S, HOLE_FACTOR = 10.0, 100.0
#: Ranges, true positions and starts must lie within 10 times the tag map's radius plus this, m.
MAP_REACH_M, MAP_REACH_FACTOR = 100.0, 10.0
#: A recorded log's time may step back this much (rows logged out of order), s; more is refused.
BACKWARDS_TOLERANCE_S = 1.0
#: A sighting is off the truth beyond this bearing error (rad) or range error (m, plus 20 % of
#: the true range); more than this fraction of them off (and at least `OFF_TRUTH_COUNT`) is
#: refused.
OFF_TRUTH_BEARING, OFF_TRUTH_RANGE, OFF_TRUTH_FRACTION, OFF_TRUTH_COUNT = 0.5, 1.5, 0.05, 5


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
    margin_s: float = SPAN_MARGIN_S,
    overlap: bool = True,
) -> None:
    """Raise `InputError` unless every file in `others` shares the controls' clock.

    controls : (its file name for messages, its times (N,) in s, sorted).
    others : (path, times (M,) s sorted, covers) per file; covers: the file must also span at
        least half of the controls' time (ground truth), not only lie within it.
    lines : whether row i of a file is its line i + 2 (False: sorted, filtered, or found in
        camera frames), for the message.
    margin_s : the least margin, s (a motion-capture system that starts a while before the
        robot's logs needs more than `SPAN_MARGIN_S`).
    overlap : whether half of each file's span must lie in the controls' (False: only the
        margin, for a file that may run on long before or after the controls).

    With the controls spanning [c0, c1] and m = max(1 s, 10 % of c1 - c0): every time lies in
    [c0 - m, c1 + m], at least half of each file's own span lies inside [c0, c1], and a file
    that covers spans at least half of [c0, c1].
    """
    c_name, c = controls[0], np.asarray(controls[1], dtype=float)
    c0, c1 = float(c[0]), float(c[-1])
    margin = max(margin_s, SPAN_MARGIN_FRACTION * (c1 - c0))
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
        elif overlap and t1 > t0 and inside < 0.5 * (t1 - t0):
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


def first_beyond(values: ArrayLike, bound: float) -> int | None:
    """The index of the first value with |value| > bound (NaN is not beyond), or None."""
    hits = np.flatnonzero(np.abs(np.asarray(values, dtype=float)) > bound)
    return int(hits[0]) if hits.size else None


def control_hole(t: ArrayLike, twist: ArrayLike) -> tuple[int, float] | None:
    """The first hole in the controls while the robot moves: (row after the hole, its length s).

    t : (N,) s, sorted; twist : (N, 3) the body twist held from each row to the next.
    A hole is a gap longer than max(`HOLE_S`, `HOLE_FACTOR` x the median gap) after a row whose
    twist is not zero. A robot at rest may leave any gap (its held control moves nothing).
    """
    t = np.asarray(t, dtype=float)
    if len(t) < 2:
        return None
    gaps = np.diff(t)
    limit = max(HOLE_S, HOLE_FACTOR * float(np.median(gaps)))
    moving = np.any(np.asarray(twist, dtype=float)[:-1] != 0.0, axis=1)
    hits = np.flatnonzero((gaps > limit) & moving)
    return (int(hits[0]) + 1, float(gaps[hits[0]])) if hits.size else None


def coincident(tag_map: dict) -> tuple[list[int], list[tuple[int, int]]]:
    """(the ids, if 2 or more tags all lie at one point, else []; pairs of ids at one point).

    Positions within 1 µm are one point.
    """
    ids = sorted(tag_map)
    if len(ids) < 2:
        return [], []
    xy = np.array([np.asarray(tag_map[i], dtype=float) for i in ids]).reshape(-1, 2)
    if float(np.ptp(xy, axis=0).max()) <= 1e-6:
        return ids, []
    pairs = []
    order = np.lexsort((xy[:, 1], xy[:, 0]))
    for a, b in itertools.pairwise(order.tolist()):
        if np.abs(xy[a] - xy[b]).max() <= 1e-6:
            pairs.append((ids[a], ids[b]))
    return [], pairs


def map_reach(tag_map: dict | None) -> tuple[np.ndarray, float] | None:
    """(the tag map's centre, how far from it a range, a position or a start may lie, m)."""
    if not tag_map:
        return None
    xy = np.array([np.asarray(v, dtype=float) for v in tag_map.values()]).reshape(-1, 2)
    centre = xy.mean(axis=0)
    radius = float(np.hypot(*(xy - centre).T).max())
    return centre, MAP_REACH_FACTOR * radius + MAP_REACH_M


def beyond_map(points: ArrayLike, tag_map: dict | None) -> tuple[int, float, float] | None:
    """The first point (x, y) too far from the tag map to belong to it: (index, its distance,
    the reach), or None (also without a map)."""
    reach = map_reach(tag_map)
    if reach is None or not len(points):
        return None
    centre, limit = reach
    d = np.hypot(*(np.asarray(points, dtype=float).reshape(-1, 2) - centre).T)
    hits = np.flatnonzero(d > limit)
    return (int(hits[0]), float(d[hits[0]]), limit) if hits.size else None


def ranges_beyond_map(ranges: ArrayLike, tag_map: dict | None) -> tuple[int, float] | None:
    """The first range longer than any sighting of the map could be (index, the reach), or None:
    the robot would stand beyond the map's reach (`map_reach`) plus the map's own size."""
    reach = map_reach(tag_map)
    if reach is None:
        return None
    centre, limit = reach
    xy = np.array([np.asarray(v, dtype=float) for v in tag_map.values()]).reshape(-1, 2)
    longest = limit + float(np.hypot(*(xy - centre).T).max())
    hits = np.flatnonzero(np.asarray(ranges, dtype=float) > longest)
    return (int(hits[0]), longest) if hits.size else None


def backwards(t: ArrayLike) -> tuple[int, float] | None:
    """The first row whose time is more than `BACKWARDS_TOLERANCE_S` earlier than the latest
    before it: (its index, how far back, s), or None."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2:
        return None
    latest = np.maximum.accumulate(t)
    back = np.concatenate([[0.0], latest[:-1] - t[1:]])
    hits = np.flatnonzero(back > BACKWARDS_TOLERANCE_S)
    return (int(hits[0]), float(back[hits[0]])) if hits.size else None


def sightings_off_truth(
    t: ArrayLike,
    tag_id: ArrayLike,
    ranges: ArrayLike,
    bearings: ArrayLike,
    truth: tuple[ArrayLike, ArrayLike],
    tag_map: dict | None,
) -> tuple[int, int, int] | None:
    """(how many sightings are off the truth, how many were compared, the first one's index) when
    too many are (`OFF_TRUTH_FRACTION`), else None.

    Each sighting of a mapped tag, at a time within the truth's span, is compared with the range
    and bearing the true pose (interpolated; the heading unwrapped) gives; off is a bearing error
    beyond `OFF_TRUTH_BEARING` or a range error beyond `OFF_TRUTH_RANGE` + 20 %.
    """
    gt_t, pose = (np.asarray(a, dtype=float) for a in truth)
    t, ids = np.asarray(t, dtype=float), np.asarray(tag_id)
    if not tag_map or len(gt_t) < 2 or not len(t):
        return None
    known = np.array([int(i) in tag_map for i in ids.tolist()], dtype=bool)
    inside = known & (t >= gt_t[0]) & (t <= gt_t[-1])
    if np.count_nonzero(inside) < OFF_TRUTH_COUNT:
        return None
    rows = np.flatnonzero(inside)
    heading = np.unwrap(pose[:, 2])
    x, y = (np.interp(t[rows], gt_t, pose[:, k]) for k in (0, 1))
    theta = np.interp(t[rows], gt_t, heading)
    tags = np.array([tag_map[int(i)] for i in ids[rows].tolist()], dtype=float).reshape(-1, 2)
    dx, dy = tags[:, 0] - x, tags[:, 1] - y
    r_hat = np.hypot(dx, dy)
    d_bearing = np.asarray(bearings, dtype=float)[rows] - (np.arctan2(dy, dx) - theta)
    d_bearing = np.abs(wrap_angle(d_bearing))
    d_range = np.abs(np.asarray(ranges, dtype=float)[rows] - r_hat)
    off = (d_bearing > OFF_TRUTH_BEARING) | (d_range > OFF_TRUTH_RANGE + 0.2 * r_hat)
    count = int(np.count_nonzero(off))
    if count <= OFF_TRUTH_FRACTION * len(rows) or count < OFF_TRUTH_COUNT:
        return None
    return count, len(rows), int(rows[np.flatnonzero(off)[0]])
