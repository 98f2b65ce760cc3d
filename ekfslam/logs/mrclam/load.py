"""Read one robot of the UTIAS MRCLAM dataset (Leung et al., IJRR 2011) into a `RunLog`.

An MRCLAM dataset folder (``MRCLAM_Dataset7/``) holds, as whitespace-separated text with ``#``
header lines and CRLF line endings:

    Barcodes.dat              subject #, barcode #
    Landmark_Groundtruth.dat  subject #, x [m], y [m], x std-dev [m], y std-dev [m]
    RobotN_Odometry.dat       time [s], forward velocity v [m/s], angular velocity ω [rad/s]
    RobotN_Measurement.dat    time [s], barcode #, range [m], bearing [rad]
    RobotN_Groundtruth.dat    time [s], x [m], y [m], θ [rad]

Subjects 1-5 are the robots, 6-20 the landmarks. The camera sits at the robot's centre, looking
along its heading, so a measurement is already the (r, φ) of eq. (10).

Nothing is dropped silently: every sighting that does not become a detection is counted in the
`MrclamLoadReport` returned beside the run. Times stay on the dataset's own clock (Unix seconds).

Beside loading, in `ekfslam.logs.mrclam.calibration`: `calibrate_commands` (an optional correction
of the logged commands, `MRCLAM_CALIBRATION`, off by default); in `ekfslam.analysis.mrclam_tuning`:
`score_robots`, `scores_table` and
``python -m studies score-mrclam N`` (the per-robot table); in the repository's studies,
`studies.mrclam_tuning.tune_noise` (the grid search behind
`ekfslam.logs.mrclam.defaults.MRCLAM_NOISE`, one setting for all robots).

``python -m ekfslam convert mrclam DATASET --robot N --out DIR`` writes a robot as a run folder.
"""

from __future__ import annotations

import dataclasses
import math
import re
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.errors import InputError
from ekfslam.files import not_a_file
from ekfslam.geometry import wrap_angle
from ekfslam.logs.mrclam.cache import mrclam_path
from ekfslam.logs.mrclam.checks import (
    DEFAULT_MAX_RANGE,
    beyond_range,
    fix_barcodes,
    swapped_subjects,
    time_offsets,
)
from ekfslam.logs.mrclam.dat import data_line, raise_at_row, read_table, require_integers
from ekfslam.logs.mrclam.defaults import NAME as MRCLAM_DEFAULTS
from ekfslam.logs.mrclam.report import BARCODES, MrclamLoadReport
from ekfslam.logs.runlog import (
    Controls,
    Detections,
    GroundTruth,
    RunLog,
    RunMeta,
    check_across_files,
    check_time_spans,
)
from ekfslam.places import shared_data_dir
from ekfslam.plausibility import (
    BACKWARDS_TOLERANCE_S,
    MAX_HEADING,
    MAX_POSITION,
    MAX_SPEED,
    MAX_TIME,
    MAX_TURN_RATE,
    backwards,
    check_clocks,
    coincident,
    first_beyond,
)

Array = NDArray[np.float64]

#: s: how long before a robot's odometry its Vicon truth may start (6-9 s in the datasets).
VICON_LEAD_S = 60.0
#: The robots' subject numbers; every other subject in Barcodes.dat is a landmark.
ROBOTS = (1, 2, 3, 4, 5)

LANDMARKS = "Landmark_Groundtruth.dat"
ROBOT_KINDS = ("Odometry", "Measurement", "Groundtruth")  # RobotN_<kind>.dat

_BARCODE_COLUMNS = ("subject", "barcode")
_LANDMARK_COLUMNS = ("subject", "x", "y", "x std-dev", "y std-dev")
_ODOMETRY_COLUMNS = ("time", "v", "w")
_MEASUREMENT_COLUMNS = ("time", "barcode", "range", "bearing")
_GROUNDTRUTH_COLUMNS = ("time", "x", "y", "theta")


def robot_file(dataset_dir: str | Path, robot: int, kind: str) -> Path:
    """Path of robot N's file of `kind` ("Odometry", "Measurement" or "Groundtruth")."""
    return Path(dataset_dir) / f"Robot{robot}_{kind}.dat"


def load_mrclam(
    dataset_dir: str | Path,
    robot: int,
    max_range: float | None = DEFAULT_MAX_RANGE,
    fix_barcode_swap: bool = True,
) -> tuple[RunLog, MrclamLoadReport]:
    """Load robot `robot` (1-5) of an MRCLAM dataset folder as a recorded run.

    Controls: each odometry row (t, v, ω) becomes a body twist (vx, vy, wz) = (v, 0, ω) held
    until the next row (a differential drive cannot move sideways). Detections: each sighting of a
    landmark (subject 6-20, found through Barcodes.dat) becomes (t, tag id = subject number, r, φ)
    with φ wrapped to [-π, π); sightings of robots and of barcodes missing from Barcodes.dat are
    dropped and counted in the report. Rows out of time order are sorted stably; rows sharing a
    timestamp are all kept, in file order.

    Start pose convention: ``meta.nominal_start`` is the ground-truth pose linearly interpolated
    at the first odometry time, with θ interpolated on the unwrapped heading (so a crossing of ±π
    between two samples does not sweep through 0). If the first odometry time is outside the
    ground truth, the nearest ground-truth pose is used and the report says so. Without
    RobotN_Groundtruth.dat (Datasets 1 and 4 as shipped here) the run has no ground truth and
    starts at the origin, as the seed's robot did: its map is scored after eq. (17).

    The checks of `ekfslam.logs.mrclam.checks`, each counted in the report: sightings beyond
    `max_range` (m; None keeps all) are dropped; with `fix_barcode_swap`, Dataset 1's swapped
    barcodes of subjects 11 and 17 are put right.

    Parameters
    ----------
    dataset_dir : folder holding Barcodes.dat, Landmark_Groundtruth.dat and RobotN_*.dat.
    robot : 1 to 5.
    max_range : m, or None for no cut (the default, `DEFAULT_MAX_RANGE`: measured in `checks`).
    fix_barcode_swap : undo a known swap in Barcodes.dat (`checks.fix_barcodes`).

    Returns
    -------
    (RunLog, MrclamLoadReport)
        The run (meta.name ``mrclam<dataset>-robot<N>``, meta.tag_map {subject: (x, y)} in m from
        Landmark_Groundtruth.dat, ground truth attached) and what was kept and dropped.

    Raises
    ------
    InputError
        A missing folder or file, a robot outside 1-5, or a malformed file (the message names
        the file, the 1-based line and the problem).
    """
    run, report, _ = load_robot(dataset_dir, robot, max_range, fix_barcode_swap)
    return run, report


def load_robot(
    dataset_dir: str | Path,
    robot: int,
    max_range: float | None = DEFAULT_MAX_RANGE,
    fix_barcode_swap: bool = True,
) -> tuple[RunLog, MrclamLoadReport, Array]:
    """`load_mrclam`, and the robot's sightings of the other robots it drops, for a team.

    Returns
    -------
    (RunLog, MrclamLoadReport, (K, 4) array)
        As `load_mrclam`, and the sightings of robots (subjects 1-5) in time order as rows
        (t [s], subject, range [m], bearing [rad] wrapped to [-π, π)); those beyond `max_range`
        are not among them (the report counts them in ``robot_sightings_dropped``).
    """
    folder = Path(dataset_dir)
    if not isinstance(robot, int | np.integer) or isinstance(robot, bool) or robot not in ROBOTS:
        raise InputError(folder, None, f"robot must be 1 to 5 (MRCLAM has 5 robots), got {robot!r}")
    robot = int(robot)
    if not folder.is_dir():
        raise InputError(folder, None, "not a folder; expected an MRCLAM_Dataset<N> folder")
    paths = {kind: robot_file(folder, robot, kind) for kind in ROBOT_KINDS}
    truth_path = paths["Groundtruth"]
    has_truth = truth_path.exists() or truth_path.is_symlink()  # a dangling link is broken
    required = [folder / BARCODES, folder / LANDMARKS, paths["Odometry"], paths["Measurement"]]
    required += [truth_path] if has_truth else []
    _require_files(folder, robot, required)
    dataset = _dataset_number(folder)

    barcode_to_subject = read_barcodes(folder / BARCODES)
    if fix_barcode_swap:
        barcode_to_subject, swap_fixed = fix_barcodes(dataset, barcode_to_subject)
    else:
        swap_fixed = False
    tag_map = read_landmarks(folder / LANDMARKS)
    table = read_table(paths["Odometry"], _ODOMETRY_COLUMNS)
    _check_plausible(paths["Odometry"], table, _ODOMETRY_COLUMNS, _ODOMETRY_BOUNDS)
    odometry, odo_unsorted, odo_order = _sorted_by_time(table, paths["Odometry"])
    measurements = read_table(paths["Measurement"], _MEASUREMENT_COLUMNS)
    _check_plausible(paths["Measurement"], measurements, _MEASUREMENT_COLUMNS, _MEASUREMENT_BOUNDS)
    _check_measurements(paths["Measurement"], measurements, barcode_to_subject, tag_map)
    measurements, meas_unsorted, meas_order = _sorted_by_time(measurements, paths["Measurement"])
    if has_truth:
        table = read_table(paths["Groundtruth"], _GROUNDTRUTH_COLUMNS)
        _check_plausible(paths["Groundtruth"], table, _GROUNDTRUTH_COLUMNS, _GROUNDTRUTH_BOUNDS)
    else:
        table = np.empty((0, 4))
    groundtruth, gt_unsorted, gt_order = _sorted_by_time(table, paths["Groundtruth"])

    controls = Controls(
        t=odometry[:, 0].copy(),
        kind="twist",
        values=np.column_stack([odometry[:, 1], np.zeros(len(odometry)), odometry[:, 2]]),
    )
    barcodes = measurements[:, 1].astype(np.int64)
    subjects = np.array([barcode_to_subject.get(b, 0) for b in barcodes.tolist()], dtype=np.int64)
    unknown = subjects == 0
    robot_sighting = np.isin(subjects, ROBOTS)
    far = beyond_range(measurements[:, 2], max_range) & ~unknown & ~robot_sighting
    keep = ~unknown & ~robot_sighting & ~far
    renamed = np.isin(subjects[keep], swapped_subjects(dataset)) if swap_fixed else keep[:0]
    detections = Detections(
        t=measurements[keep, 0].copy(),
        tag_id=subjects[keep],
        range=measurements[keep, 2].copy(),
        bearing=_wrapped(measurements[keep, 3]),
    )
    gt_pose = groundtruth[:, 1:4].copy()
    gt_pose[:, 2] = _wrapped(gt_pose[:, 2])
    truth = GroundTruth(t=groundtruth[:, 0].copy(), pose=gt_pose) if has_truth else None

    start_time = float(controls.t[0])
    if truth is not None:
        nominal_start = interpolate_pose(truth.t, truth.pose, start_time)
    else:
        nominal_start = np.zeros(3)  # unknown: the origin, as the seed's robot (eq. 17 aligns)
    meta = RunMeta(
        name=f"mrclam{dataset}-robot{robot}",
        source="recorded",
        nominal_start=nominal_start,
        tag_map=tag_map,
        defaults=MRCLAM_DEFAULTS,  # the tuned noise and filter choices of `defaults`
    )
    gaps = np.diff(controls.t)
    report = MrclamLoadReport(
        dataset=dataset,
        robot=robot,
        odometry_rows=len(odometry),
        odometry_duplicate_times=int(np.count_nonzero(gaps == 0.0)),
        odometry_max_gap_s=float(gaps.max()) if gaps.size else 0.0,
        odometry_out_of_order=odo_unsorted,
        measurement_rows=len(measurements),
        measurements_kept=int(np.count_nonzero(keep)),
        robot_sightings_dropped=int(np.count_nonzero(robot_sighting)),
        unknown_barcodes_dropped=int(np.count_nonzero(unknown)),
        unknown_barcodes=frozenset(int(b) for b in np.unique(barcodes[unknown])),
        measurement_out_of_order=meas_unsorted,
        groundtruth_rows=len(groundtruth),
        groundtruth_first_time=float(truth.t[0]) if truth is not None else None,
        groundtruth_last_time=float(truth.t[-1]) if truth is not None else None,
        groundtruth_out_of_order=gt_unsorted,
        start_time=start_time,
        start_inside_groundtruth=has_truth
        and bool(groundtruth[0, 0] <= start_time <= groundtruth[-1, 0]),
        max_range=max_range,
        beyond_range_dropped=int(np.count_nonzero(far)),
        barcode_swap_fixed=swap_fixed,
        barcode_swap_renamed=int(np.count_nonzero(renamed)),
        time_offsets=time_offsets(odometry[:, 0], measurements[:, 0]),
    )
    run = RunLog(meta=meta, controls=controls, detections=detections, groundtruth=truth)
    near_robot = robot_sighting & ~beyond_range(measurements[:, 2], max_range)
    robots_seen = np.column_stack(
        [
            measurements[near_robot, 0],
            subjects[near_robot].astype(np.float64),
            measurements[near_robot, 2],
            _wrapped(measurements[near_robot, 3]),
        ]
    )
    # the measurements share the odometry's clock; the Vicon truth's cover is only reported
    names = (paths["Odometry"].name, paths["Measurement"].name, paths["Groundtruth"].name)
    check_time_spans(dataclasses.replace(run, groundtruth=None), folder, names, lines=False)
    if truth is not None:  # on the odometry's clock too, though it need not cover the run
        others = [(paths["Groundtruth"], truth.t, False)]
        check_clocks((names[0], controls.t), others, False, margin_s=VICON_LEAD_S, overlap=False)
    kept_rows = np.flatnonzero(keep)
    lines: dict[str, Callable[[int], int]] = {
        names[0]: lambda row: data_line(paths["Odometry"], int(odo_order[row])),
        names[1]: lambda row: data_line(paths["Measurement"], int(meas_order[kept_rows[row]])),
        names[2]: lambda row: data_line(paths["Groundtruth"], int(gt_order[row])),
    }
    check_across_files(run, folder, names, sorted_rows=lines)
    return run, report, robots_seen


def interpolate_pose(t: ArrayLike, pose: ArrayLike, at: float) -> Array:
    """The pose (x, y, θ) at time `at`, linearly interpolated between ground-truth samples.

    Parameters
    ----------
    t : (K,) s, non-decreasing.
    pose : (K, 3) (x, y, θ) in m, m, rad.
    at : s; clamped to [t[0], t[-1]].

    Returns
    -------
    (3,) with θ interpolated on the unwrapped heading, then wrapped to [-π, π).
    """
    t = np.asarray(t, dtype=np.float64)
    pose = np.asarray(pose, dtype=np.float64)
    heading = np.unwrap(pose[:, 2])
    return np.array(
        [
            np.interp(at, t, pose[:, 0]),
            np.interp(at, t, pose[:, 1]),
            wrap_angle(float(np.interp(at, t, heading))),
        ]
    )


def read_barcodes(path: str | Path) -> dict[int, int]:
    """Barcodes.dat as {barcode: subject}; a barcode or subject listed twice is an InputError."""
    path = Path(path)
    table = read_table(path, _BARCODE_COLUMNS)
    require_integers(path, table, _BARCODE_COLUMNS, (0, 1))
    mapping: dict[int, int] = {}
    first_row_of_subject: dict[int, int] = {}
    for row, (subject, barcode) in enumerate(table.astype(np.int64).tolist()):
        if subject < 1 or barcode < 0:
            raise_at_row(path, row, f"subject {subject} must be >= 1, barcode {barcode} >= 0")
        if barcode in mapping:
            raise_at_row(
                path,
                row,
                f"barcode {barcode} is mapped twice (subjects {mapping[barcode]} and {subject})",
            )
        if subject in first_row_of_subject:
            raise_at_row(path, row, f"subject {subject} has two barcodes")
        mapping[barcode] = subject
        first_row_of_subject[subject] = row
    return mapping


def read_landmarks(path: str | Path) -> dict[int, Array]:
    """Landmark_Groundtruth.dat as {subject: array (2,) (x, y) in m}."""
    path = Path(path)
    table = read_table(path, _LANDMARK_COLUMNS)
    require_integers(path, table, _LANDMARK_COLUMNS, (0,))
    tag_map: dict[int, Array] = {}
    for row, (subject, x, y, _sx, _sy) in enumerate(table.tolist()):
        subject = int(subject)
        if subject in ROBOTS:
            raise_at_row(path, row, f"subject {subject} is a robot, not a landmark")
        if subject in tag_map:
            raise_at_row(path, row, f"landmark {subject} is listed twice")
        if max(abs(x), abs(y)) > MAX_POSITION:
            raise_at_row(path, row, f"landmark {subject} at ({x!r}, {y!r}) m: not plausible")
        tag_map[subject] = np.array([x, y])
    at_one, pairs = coincident(tag_map)
    if at_one:
        raise InputError(
            path,
            None,
            f"all {len(at_one)} landmarks are at one point {tag_map[at_one[0]].tolist()}: eq. (17) "
            "cannot find the map's rotation from it",
        )
    for a, b in pairs:
        row = sorted(tag_map).index(b)
        warnings.warn(
            f"{path}:{data_line(path, row)}: landmarks {a} and {b} are at the same point",
            stacklevel=3,
        )
    return tag_map


def _wrapped(angle: Array) -> Array:
    """Angles wrapped to [-π, π), leaving those already inside bit-for-bit as recorded."""
    inside = (angle >= -math.pi) & (angle < math.pi)
    return np.where(inside, angle, wrap_angle(angle))


def _dataset_number(folder: Path) -> str:
    match = re.search(r"(\d+)$", folder.resolve().name)
    return match.group(1) if match else folder.name


def _require_files(folder: Path, robot: int, paths: list[Path]) -> None:
    missing = [p for p in paths if not p.exists() and not p.is_symlink()]
    if missing:
        names = ", ".join(p.name for p in missing)
        raise InputError(
            missing[0], None, f"file not found: robot {robot} needs {names} in {folder}"
        )
    for path in paths:  # there, but a folder, a FIFO, a device, a dangling link
        problem = not_a_file(path)
        if problem is not None:
            raise InputError(path, None, f"{problem}; robot {robot} reads it as a table")


def _sorted_by_time(table: Array, path: Path) -> tuple[Array, int, np.ndarray]:
    """Stable sort on column 0: (the table, how many rows were earlier than the row before,
    each sorted row's row in the file).

    A step back of more than `BACKWARDS_TOLERANCE_S` is refused, naming its line: two logs
    pasted together (another robot's rows appended), not rows logged out of order. Smaller
    steps are sorted, counted in the report, and warned about with the first one's line.
    """
    back = backwards(table[:, 0])
    if back is not None:
        row, seconds = back
        raise_at_row(
            path,
            row,
            f"time {table[row, 0]!r} s goes back {seconds:.6g} s from the rows before it (more "
            f"than the {BACKWARDS_TOLERANCE_S:g} s a log may be out of order): two logs pasted "
            "together, such as another robot's rows?",
        )
    steps = np.diff(table[:, 0]) < 0
    out_of_order = int(np.count_nonzero(steps))
    order = np.arange(len(table))
    if out_of_order:
        first = int(np.flatnonzero(steps)[0]) + 1
        warnings.warn(
            f"{path}:{data_line(path, first)}: {out_of_order} row(s) out of time order (at most "
            f"{float((-np.diff(table[:, 0])).max()):.3g} s earlier than the row before): sorted",
            stacklevel=3,
        )
        order = np.argsort(table[:, 0], kind="stable")
        table = table[order]
    return table, out_of_order, order


#: column -> (the largest plausible |value|, unit, what it is) of each file (`ekfslam.plausibility`)
_ODOMETRY_BOUNDS = {
    0: (MAX_TIME, "s", "a time"),
    1: (MAX_SPEED, "m/s", "a speed"),
    2: (MAX_TURN_RATE, "rad/s", "a turn rate"),
}
# the measurements' and the truth's times: the clock check names both files of two clocks
_MEASUREMENT_BOUNDS = {2: (MAX_POSITION, "m", "a range")}
_GROUNDTRUTH_BOUNDS = {
    1: (MAX_POSITION, "m", "a position"),
    2: (MAX_POSITION, "m", "a position"),
    3: (MAX_HEADING, "rad", "a heading (degrees by mistake?)"),
}


def _check_plausible(
    path: Path, table: Array, names: tuple[str, ...], bounds: dict[int, tuple[float, str, str]]
) -> None:
    """Refuse the first row with a value beyond its column's plausible bound, naming its line."""
    first = None
    for col, (bound, unit, what) in bounds.items():
        row = first_beyond(table[:, col], bound)
        if row is not None and (first is None or row < first[0]):
            first = (row, col, bound, unit, what)
    if first is not None:
        row, col, bound, unit, what = first
        raise_at_row(
            path,
            row,
            f"{names[col]} {float(table[row, col])!r} {unit} is not plausible as {what} "
            f"(beyond {bound:g} {unit})",
        )


def _check_measurements(path: Path, table: Array, subjects: dict, tag_map: dict) -> None:
    """Our own reader's rules (`ekfslam.logs.runlog`): range >= 0, bearing in [-π, π], and every
    sighted landmark (a subject of Barcodes.dat, not a robot) in Landmark_Groundtruth.dat."""
    require_integers(path, table, _MEASUREMENT_COLUMNS, (1,))
    for row, (_, barcode, r, b) in enumerate(table.tolist()):
        s = subjects.get(int(barcode), ROBOTS[0])
        if r < 0:
            raise_at_row(path, row, f"negative range {r:g} m")
        if abs(b) > math.pi:
            raise_at_row(path, row, f"bearing {b!r} rad is outside [-pi, pi] (degrees?)")
        if s not in ROBOTS and s not in tag_map:
            where = f"(barcode {int(barcode)} in {BARCODES}) is not in {LANDMARKS}"
            raise_at_row(path, row, f"landmark {s} {where}")


def find_dataset(n: int = 7) -> Path:
    """Where MRCLAM dataset n is on this machine, for notebooks and scripts.

    Looks in ``mrclam/`` of `shared_data_dir()`, then in the download cache of
    ``python -m ekfslam fetch mrclam N``.

    Raises
    ------
    InputError
        Not found anywhere; the message says how to fetch it.
    """
    shared = shared_data_dir()
    places = [shared / "mrclam" / f"MRCLAM_Dataset{n}"] if shared is not None else []
    for place in [*places, mrclam_path(n)]:
        if (place / BARCODES).is_file():
            return place
    raise InputError(
        mrclam_path(n), None, f"dataset {n} not found; run `python -m ekfslam fetch mrclam {n}`"
    )
