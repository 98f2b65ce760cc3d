"""A run log from arrays in memory: your own robot's log, replayed without writing a run folder.

`run_from_arrays` takes what a robot logs as numpy arrays whose columns are those of the run
format's files (``data/README.md``): controls ``t, vx, vy, wz`` (or ``t, w1, w2, w3, w4``),
detections ``t, tag_id, range, bearing`` and, if you have them, true poses ``t, x, y, theta``.
It checks them as ``read_run`` checks a run folder and returns the `RunLog` that
``ekfslam.replay`` takes::

    run = ekfslam.run_from_arrays(
        controls=np.column_stack([t, vx, vy, wz]),  # s, m/s, m/s, rad/s
        detections=np.column_stack([td, tag_id, r, bearing]),  # s, id, m, rad
    )
    result = ekfslam.replay(run)  # result.landmarks: {tag id: (x, y)}

A problem is one line naming the array and the row: ``detections[7]: negative range -1.5 m (a
range is >= 0)``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

from ekfslam.core.kinematics import MecanumGeometry
from ekfslam.errors import InputError
from ekfslam.logs.runlog import (
    CONTROL_COLUMNS,
    CONTROLS_CSV,
    DETECTIONS_CSV,
    GROUNDTRUTH_CSV,
    RUN_JSON,
    Controls,
    Detections,
    GroundTruth,
    RunLog,
    RunMeta,
    validate_run,
)

#: the run format's file names in the reader's messages -> the arrays they are here
_ARRAYS = {
    RUN_JSON: "run_from_arrays",
    CONTROLS_CSV: "controls",
    DETECTIONS_CSV: "detections",
    GROUNDTRUTH_CSV: "groundtruth",
}
_WORDS = {
    "run.json's tag_map": "tag_map",
    "the file has a header but no rows": "the array has no rows",
    "(delete the file if there is no truth)": "(pass groundtruth=None if there is no truth)",
    **{name: array for name, array in _ARRAYS.items() if name != RUN_JSON},
}
#: controls' width -> their kind: t and a body twist, or t and four wheel speeds
_KINDS = {len(columns): kind for kind, columns in CONTROL_COLUMNS.items()}


def run_from_arrays(
    *,
    controls: ArrayLike,
    detections: ArrayLike,
    start: ArrayLike = (0.0, 0.0, 0.0),
    robot: MecanumGeometry | None = None,
    tag_map: Mapping[int, ArrayLike] | None = None,
    groundtruth: ArrayLike | None = None,
    name: str = "arrays",
) -> RunLog:
    """A checked `RunLog` from arrays, with the columns of the run format's files.

    Parameters
    ----------
    controls
        (N, 4): ``t, vx, vy, wz``, the time (s, never decreasing) and the body twist, forward
        and left speed (m/s) and turn rate (rad/s, counter-clockwise). Or (N, 5):
        ``t, w1, w2, w3, w4``, the wheel speeds (rad/s) front left, front right, rear left, rear
        right, each positive when it rolls the robot forward; these need `robot`. Each row holds
        until the next row's time.
    detections
        (M, 4): ``t, tag_id, range, bearing``, each tag sighting's time (s, on the controls'
        clock), the tag's id (a whole number, as ``np.loadtxt`` gives it: a float), range (m)
        and bearing (rad in [-π, π], counter-clockwise, 0 straight ahead) from the robot's
        centre and heading. M may be 0.
    start
        (3,): the pose (x, y, θ) in m, m, rad the filter starts from.
    robot
        the mecanum geometry, needed with wheel speeds.
    tag_map
        {tag id: (x, y)} m, the true tags if you surveyed them: the map is then scored (eq. 17).
    groundtruth
        (K, 4): ``t, x, y, theta``, the true poses (s, m, m, rad) if you have them: the
        trajectory is then scored.
    name
        the run's label in tables and plots.

    Returns
    -------
    RunLog
        ``source="recorded"``; replay it with ``ekfslam.replay(run)``.

    Raises
    ------
    InputError
        One line naming the array (and its row) and what is wrong: a shape, a time going
        backwards, a NaN, a negative range, a bearing in degrees, clocks that do not overlap.
    """
    c = _table("controls", controls)
    kind = _KINDS.get(c.shape[1])
    if kind is None:
        raise InputError(
            "controls",
            None,
            f"has {c.shape[1]} columns: 4 are t, vx, vy, wz and 5 are t, w1, w2, w3, w4",
        )
    if kind == "wheels" and robot is None:
        raise InputError(
            "controls",
            None,
            "5 columns are wheel speeds, which need robot=MecanumGeometry(wheel_radius, lx, ly)",
        )
    d = _table("detections", detections, 4)
    truth = None
    if groundtruth is not None:
        g = _table("groundtruth", groundtruth, 4)
        truth = GroundTruth(t=g[:, 0], pose=g[:, 1:])
    meta = RunMeta(
        name=name,
        source="recorded",
        nominal_start=_start(start),
        robot=robot,
        tag_map=None if tag_map is None else {_tag(t): _point(t, xy) for t, xy in tag_map.items()},
    )
    run = RunLog(
        meta=meta,
        controls=Controls(t=c[:, 0], kind=kind, values=c[:, 1:]),
        detections=Detections(t=d[:, 0], tag_id=_ids(d[:, 1]), range=d[:, 2], bearing=d[:, 3]),
        groundtruth=truth,
    )
    try:
        validate_run(run)
    except InputError as problem:
        raise _in_arrays(problem) from None
    return run


def _in_arrays(problem: InputError) -> InputError:
    """The reader's ``detections.csv:9: ...`` as ``detections[7]: ...`` (row 7 is line 9)."""
    where = _ARRAYS.get(problem.path, problem.path)
    if problem.line is not None and problem.path != RUN_JSON:
        where = f"{where}[{problem.line - 2}]"
    text = problem.problem
    for word, instead in _WORDS.items():
        text = text.replace(word, instead)
    return InputError(where, None, text)


def _floats(what: str, values: ArrayLike) -> np.ndarray:
    try:
        return np.array(values, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InputError(what, None, f"must be numbers: {err}") from None


def _table(what: str, values: ArrayLike, columns: int | None = None) -> np.ndarray:
    """`values` as an (N, columns) float array; an empty list is a table of no rows."""
    array = _floats(what, values)
    if array.size == 0 and columns is not None:
        array = array.reshape(0, columns)
    if array.ndim != 2 or (columns is not None and array.shape[1] != columns):
        expected = f"(N, {columns})" if columns is not None else "(N, columns)"
        raise InputError(what, None, f"has shape {array.shape}, expected {expected}")
    return array


def _start(start: ArrayLike) -> np.ndarray:
    pose = _floats("start", start)
    if pose.shape != (3,):
        raise InputError("start", None, f"has shape {pose.shape}, expected (3,): x, y, theta")
    return pose


def _point(tag: int, xy: ArrayLike) -> np.ndarray:
    point = _floats(f"tag_map[{tag}]", xy)
    if point.shape != (2,):
        raise InputError(f"tag_map[{tag}]", None, f"has shape {point.shape}, expected (2,)")
    return point


def _ids(column: np.ndarray) -> np.ndarray:
    """Tag ids as int64: whole numbers only (``np.loadtxt`` reads every column as float)."""
    bad = np.flatnonzero(
        ~np.isfinite(column) | (column != np.round(column)) | (np.abs(column) >= 2.0**63)
    )
    if bad.size:
        row = int(bad[0])
        raise InputError(
            f"detections[{row}]", None, f"tag_id {float(column[row])!r} is not a whole id"
        )
    return column.astype(np.int64)


def _tag(tag: object) -> int:
    if isinstance(tag, bool) or not isinstance(tag, int | np.integer):
        raise InputError("tag_map", None, f"tag id {tag!r} is not an integer")
    return int(tag)
