"""A run log from arrays in memory: your own robot's log, replayed without writing a run folder.

`run_from_arrays` takes what a robot logs (time-stamped controls and tag sightings, and the
true poses if you have them) as numpy arrays, checks them as ``read_run`` checks a run folder's
files, and returns the `RunLog` that ``ekfslam.replay`` takes::

    run = ekfslam.run_from_arrays(
        controls_t=t, twist=twist,  # (N,) s and (N, 3) vx, vy (m/s), wz (rad/s)
        detections_t=td, tag_id=ids, range=r, bearing=b,  # (M,) each: s, int, m, rad
        start=(0.0, 0.0, 0.0),
    )
    result = ekfslam.replay(run)  # result.landmarks: {tag id: (x, y)}

A problem is one line naming the argument and the row: ``detections[7]: negative range -1.5 m
(a range is >= 0)``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike

from ekfslam.core.kinematics import MecanumGeometry
from ekfslam.errors import InputError
from ekfslam.logs.runlog import (
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

#: the run format's file names in the reader's messages -> the arrays they came from here
_ARRAYS = {
    RUN_JSON: "run_from_arrays",
    CONTROLS_CSV: "controls",
    DETECTIONS_CSV: "detections",
    GROUNDTRUTH_CSV: "groundtruth",
}
_WORDS = {
    "run.json's tag_map": "tag_map",
    "the file has a header but no rows": "controls_t is empty",
    "(delete the file if there is no truth)": "(pass groundtruth=None if there is no truth)",
    **{name: array for name, array in _ARRAYS.items() if name != RUN_JSON},
}


def run_from_arrays(
    *,
    controls_t: ArrayLike,
    twist: ArrayLike | None = None,
    wheels: ArrayLike | None = None,
    detections_t: ArrayLike,
    tag_id: ArrayLike,
    range: ArrayLike,
    bearing: ArrayLike,
    start: ArrayLike = (0.0, 0.0, 0.0),
    robot: MecanumGeometry | None = None,
    tag_map: Mapping[int, ArrayLike] | None = None,
    groundtruth_t: ArrayLike | None = None,
    groundtruth: ArrayLike | None = None,
    name: str = "arrays",
) -> RunLog:
    """A checked `RunLog` from arrays: what ``read_run`` returns for a run folder.

    Parameters
    ----------
    controls_t
        (N,) s, the controls' times, never decreasing; each row holds until the next.
    twist
        (N, 3): the body twist vx, vy (m/s, forward and left) and wz (rad/s, counter-clockwise).
    wheels
        (N, 4) rad/s: instead of `twist`, the wheel speeds front left, front right, rear left,
        rear right, each positive when it rolls the robot forward; needs `robot`.
    detections_t, tag_id, range, bearing
        (M,) each: the sightings' times (s, on the controls' clock), the tags' ids (whole
        numbers; floats such as ``np.loadtxt`` gives are accepted when whole), range (m) and
        bearing (rad in [-π, π], counter-clockwise, 0 straight ahead) from the robot's centre
        and heading. M may be 0.
    start
        (3,) the pose (x, y, θ) in m, m, rad the filter starts from.
    robot
        the mecanum geometry; needed with `wheels`.
    tag_map
        {tag id: (x, y)} m, the true tags if you surveyed them: the map is then scored (eq. 17).
    groundtruth_t, groundtruth
        (K,) s and (K, 3) true poses (x, y, θ), if you have them (ATE against them).
    name
        the run's label in tables and plots.

    Returns
    -------
    RunLog
        ``source="recorded"``; replay it with ``ekfslam.replay(run)``.

    Raises
    ------
    InputError
        One line naming the argument (and the row) and what is wrong: a shape, a time going
        backwards, a NaN, a negative range, a bearing in degrees, clocks that do not overlap.
    """
    if (twist is None) == (wheels is None):
        raise InputError("run_from_arrays", None, "give the controls as twist= or wheels=, once")
    kind = "twist" if twist is not None else "wheels"
    if kind == "wheels" and robot is None:
        raise InputError(
            "wheels", None, "wheel speeds need robot=MecanumGeometry(wheel_radius, lx, ly)"
        )
    if (groundtruth_t is None) != (groundtruth is None):
        raise InputError("groundtruth", None, "give groundtruth_t and groundtruth together")
    t = _floats("controls_t", controls_t, 1)
    columns = 3 if kind == "twist" else 4
    values = _floats(kind, twist if twist is not None else wheels, 2, len(t), columns)
    td = _floats("detections_t", detections_t, 1)
    sightings = {
        "tag_id": _whole("tag_id", tag_id, len(td)),
        "range": _floats("range", range, 1, len(td)),
        "bearing": _floats("bearing", bearing, 1, len(td)),
    }
    truth = None
    if groundtruth_t is not None:
        tg = _floats("groundtruth_t", groundtruth_t, 1)
        truth = GroundTruth(t=tg, pose=_floats("groundtruth", groundtruth, 2, len(tg), 3))
    meta = RunMeta(
        name=name,
        source="recorded",
        nominal_start=_floats("start", start, 1, 3),
        robot=robot,
        tag_map=None
        if tag_map is None
        else {_tag(tag): _floats(f"tag_map[{tag}]", xy, 1, 2) for tag, xy in tag_map.items()},
    )
    run = RunLog(
        meta=meta,
        controls=Controls(t=t, kind=kind, values=values),
        detections=Detections(t=td, **sightings),
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


def _floats(what: str, values: ArrayLike, ndim: int, *shape: int) -> np.ndarray:
    """`values` as a float array of `ndim` dimensions whose leading sizes are `shape`."""
    try:
        array = np.array(values, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InputError(what, None, f"must be numbers: {err}") from None
    want = (*shape, *(None,) * (ndim - len(shape)))
    if array.ndim != ndim or any(
        w not in (None, n) for w, n in zip(want, array.shape, strict=True)
    ):
        sizes = ["N" if w is None else str(w) for w in want]
        expected = "(" + ", ".join(sizes) + ("," if ndim == 1 else "") + ")"
        raise InputError(what, None, f"has shape {array.shape}, expected {expected}")
    return array


def _whole(what: str, values: ArrayLike, m: int) -> np.ndarray:
    """Tag ids as int64; floats only when whole (``np.loadtxt`` reads every column as float)."""
    array = np.asarray(values)
    if np.issubdtype(array.dtype, np.integer):
        return _shaped(what, array.astype(np.int64), m)
    ids = _floats(what, array, 1, m)
    bad = np.flatnonzero(~np.isfinite(ids) | (ids != np.round(ids)) | (np.abs(ids) >= 2.0**63))
    if bad.size:
        raise InputError(f"{what}[{bad[0]}]", None, f"{float(ids[bad[0]])!r} is not a whole tag id")
    return ids.astype(np.int64)


def _shaped(what: str, array: np.ndarray, m: int) -> np.ndarray:
    if array.shape != (m,):
        raise InputError(what, None, f"has shape {array.shape}, expected ({m},)")
    return array


def _tag(tag: object) -> int:
    if isinstance(tag, bool) or not isinstance(tag, int | np.integer):
        raise InputError("tag_map", None, f"tag id {tag!r} is not an integer")
    return int(tag)
