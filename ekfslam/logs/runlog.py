"""The run-log format: what a robot (real or simulated) records, and how ekfslam reads it back.

A run is a folder::

    run.json          format version, units, rates, robot, camera mounting, nominal start, tag map
    controls.csv      time + wheel speeds (w1..w4) or body twist (vx, vy, wz); header says which
    detections.csv    time, tag id, range, bearing (robot frame); optionally each sighting's
                      sigma_range and sigma_bearing (its own observation noise)
    groundtruth.csv   optional: time, x, y, theta
    frames.csv, ...   optional: a run logged as camera frames (see `ekfslam.logs.frames`); such a
                      run may come without detections.csv until ``python -m ekfslam detect`` makes
                      it

The format is specified, with units and an example, in ``data/README.md``. The reader validates
strictly and raises `ekfslam.errors.InputError` naming the file, the line and the problem.
run.json has its own module, `ekfslam.logs.runjson` (`RunMeta`, also importable from here, as
the type of `RunLog.meta`), and the CSV text rules theirs, `ekfslam.logs.csvtable`. The writer
prints every float with ``repr`` (shortest round-trip), so ``read_run`` gives back the very same
bits that ``write_run`` was given. Asked for ``decimals`` (simulated runs use
`SIMULATED_DECIMALS`), it first rounds every float to that many decimals: the last bits of a
simulated value depend on the CPU's vector unit (numpy's SIMD paths), the rounded text does not,
and what was written still reads back exactly.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ekfslam import checks
from ekfslam.core.kinematics import MecanumGeometry, wheels_to_twist
from ekfslam.errors import InputError
from ekfslam.files import atomic_write_all, new_folder, not_a_file, probe_output
from ekfslam.logs.csvtable import csv_text, read_table
from ekfslam.logs.runjson import RunMeta, check_meta, check_shape, meta_json, read_meta
from ekfslam.plausibility import (
    MAX_HEADING,
    MAX_POSITION,
    MAX_SPEED,
    MAX_TIME,
    MAX_TURN_RATE,
    MAX_WHEEL_SPEED,
    beyond_map,
    check_clocks,
    control_hole,
    ranges_beyond_map,
    sightings_off_truth,
)

RUN_JSON, CONTROLS_CSV = "run.json", "controls.csv"
DETECTIONS_CSV, GROUNDTRUTH_CSV = "detections.csv", "groundtruth.csv"
CONTROL_COLUMNS = {"wheels": ("t", "w1", "w2", "w3", "w4"), "twist": ("t", "vx", "vy", "wz")}
DETECTION_COLUMNS = ("t", "tag_id", "range", "bearing")
#: Optional last two columns of detections.csv: each sighting's σ_r (m) and σ_φ (rad) of eq. (11).
SIGMA_COLUMNS = ("sigma_range", "sigma_bearing")
DETECTION_LAYOUTS = {
    "detections": DETECTION_COLUMNS,
    "detections with noise": DETECTION_COLUMNS + SIGMA_COLUMNS,
}
# Decimals of every float in a simulated run's CSVs: 1 ns, 1 nm, 1 nrad. Far below any noise we
# simulate (mm, mrad), far above the 1e-16 that numpy's SIMD code paths change between CPUs.
SIMULATED_DECIMALS = 9
GROUNDTRUTH_COLUMNS = ("t", "x", "y", "theta")

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Controls:
    """Commanded (or measured) motion, one row per sample, held until the next row's time.

    t : (N,) seconds, non-decreasing.
    kind : "wheels" -> values (N, 4) wheel speeds w1..w4 in rad/s (order FL, FR, RL, RR, see
           `ekfslam.core.kinematics`); "twist" -> values (N, 3) body twist vx, vy (m/s), wz (rad/s).
    """

    t: Array
    kind: Literal["wheels", "twist"]
    values: Array

    def twist(self, geometry: MecanumGeometry | None = None) -> Array:
        """(N, 3) body twist (vx, vy, ωz) in m/s, m/s, rad/s, whatever the kind.

        The twist is what the motion model integrates (seed eq. 4); wheel speeds are mapped through
        `ekfslam.core.kinematics.wheels_to_twist` and so need the robot's `geometry`.
        """
        if self.kind == "twist":
            return np.array(self.values, dtype=float)
        if geometry is None:
            raise ValueError("wheel-speed controls need the robot geometry to give a twist")
        return wheels_to_twist(self.values, geometry)


@dataclass(frozen=True, eq=False)
class Detections:
    """Landmark sightings: t (M,) s, tag_id (M,) int, range (M,) m, bearing (M,) rad in [-π, π).

    Range and bearing are measured from the robot's centre and heading (the camera mounting has
    already been applied).

    sigma_range (M,) m, sigma_bearing (M,) rad : optional, each sighting's own observation noise
    (σ_r, σ_φ of eq. 11; both or neither): a sensor whose noise depends on the sighting (a range
    and bearing converted from Cartesian x, y, a stereo range growing with distance) states it
    here, and a replay uses it instead of `ekfslam.core.noise.NoiseConfig`'s one σ_r and σ_φ
    (`NoiseConfig.per_sighting`). None: every sighting has the replay's noise.
    """

    t: Array
    tag_id: NDArray[np.int64]
    range: Array
    bearing: Array
    sigma_range: Array | None = None
    sigma_bearing: Array | None = None

    @property
    def has_sigmas(self) -> bool:
        """Whether the sightings carry their own σ_r and σ_φ."""
        return self.sigma_range is not None


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """True poses: t (K,) s and pose (K, 3) as (x, y, θ) in m, m, rad."""

    t: Array
    pose: Array


@dataclass(frozen=True, eq=False)
class RunLog:
    """One run: metadata, controls, detections and (optionally) ground truth."""

    meta: RunMeta
    controls: Controls
    detections: Detections
    groundtruth: GroundTruth | None = None

    def control_twist(self) -> Array:
        """(N, 3) body twist of the controls, converted with the run's robot geometry if needed."""
        return self.controls.twist(self.meta.robot)


# ---------------------------------------------------------------------------------------------
# Reading


def read_run(folder: str | os.PathLike, *, detections: Detections | None = None) -> RunLog:
    """Read and validate a run folder (see ``data/README.md``).

    `detections`, when given, replace detections.csv (which is then not read and need not
    exist): `ekfslam.logs.frames.read_frames_run` passes the detections it found in the run's
    frames.

    Raises
    ------
    InputError
        On the first problem found, naming the file, its 1-based line (header = line 1) and what
        is wrong, e.g. ``controls.csv:57: time 12.4 s is earlier than the previous row (12.45 s)``.
    """
    folder = checks.path(folder, "read_run: folder")
    if detections is not None:
        checks.instance(detections, Detections, "read_run: detections")
    if not folder.is_dir():
        problem = "is not a folder" if folder.exists() else "run folder not found"
        raise InputError(folder, None, f"{problem}; a run is a folder holding {_FILES_HINT}")
    for name in (RUN_JSON, CONTROLS_CSV):
        require_file(folder / name, f"a run folder holds {_FILES_HINT}")
    meta = read_meta(folder / RUN_JSON)
    if detections is None:
        hint = f"a run folder holds {_FILES_HINT}"
        if meta.frames is not None:
            hint = (
                "this run is logged as camera frames: make it with "
                f"`python -m ekfslam detect {folder} --in-place`, or replay the frames directly "
                "with "
                f"`python -m ekfslam run {folder}`"
            )
        require_file(folder / DETECTIONS_CSV, hint)

    path = folder / CONTROLS_CSV
    kind, columns = read_table(path, CONTROL_COLUMNS)
    if kind == "wheels" and meta.robot is None:
        raise InputError(
            path,
            1,
            'wheel speeds need the robot geometry, but run.json has no "robot"'
            ' (add {"type": "mecanum", "wheel_radius": m, "lx": m, "ly": m})',
        )
    controls = Controls(t=columns[0], kind=kind, values=np.column_stack(columns[1:]))
    _check_controls(controls, path)

    path = folder / DETECTIONS_CSV
    found_in_frames = detections is not None
    if detections is None:
        _, (t, tag_id, rng, bearing, *sigmas) = read_table(path, DETECTION_LAYOUTS)
        detections = Detections(t, tag_id, rng, bearing, *sigmas)
    _check_detections(detections, path, meta.tag_map)

    groundtruth = None
    path = folder / GROUNDTRUTH_CSV
    if path.exists() or path.is_symlink():  # a dangling link is a broken truth, not no truth
        require_file(path, "ground truth is a file (t,x,y,theta); delete it if there is none")
        _, columns = read_table(path, {"groundtruth": GROUNDTRUTH_COLUMNS})
        groundtruth = GroundTruth(t=columns[0], pose=np.column_stack(columns[1:]))
        _check_groundtruth(groundtruth, path)
    run = RunLog(meta=meta, controls=controls, detections=detections, groundtruth=groundtruth)
    if found_in_frames:  # the detections' times are the frames': name the file that has them
        check_time_spans(run, folder, (CONTROLS_CSV, "frames.csv", GROUNDTRUTH_CSV), lines=False)
    else:
        check_time_spans(run, folder)
    check_across_files(run, folder, lines=not found_in_frames)
    return run


def require_file(path: Path, hint: str) -> None:
    """Raise `InputError` unless `path` is a regular file (`ekfslam.files.not_a_file`: missing,
    a folder, a dangling link or a loop, a FIFO, a device such as a link to /dev/null)."""
    problem = not_a_file(path)
    if problem is not None:
        raise InputError(path, None, f"{problem}; {hint}")


_FILES_HINT = (
    "run.json, controls.csv, detections.csv and optionally groundtruth.csv (data/README.md)"
)


# ---------------------------------------------------------------------------------------------
# Validation (shared by reader and writer)


_RUN_HINT = (
    "read a run folder first (ekfslam.read_run(folder)) or simulate one (ekfslam.simulate())"
)


def check_replayable(run: RunLog, name: str) -> None:
    """What a replay reads of `run`, checked before it starts: a `RunLog` (`name` says whose
    argument) whose controls and detections are finite, in time order and plausible.

    Fast (a few vectorised tests, no row loop): a run built in memory with a NaN wheel speed is
    caught here, and only then does `validate_run` look for the row to name.
    """
    checks.instance(run, RunLog, name, _RUN_HINT)
    c, d = run.controls, run.detections
    bound = MAX_WHEEL_SPEED if c.kind == "wheels" else min(MAX_SPEED, MAX_TURN_RATE)
    try:
        t, values = np.asarray(c.t, dtype=float), np.asarray(c.values, dtype=float)
        det = [np.asarray(getattr(d, n)) for n in DETECTION_COLUMNS]
        ok = (
            c.kind in CONTROL_COLUMNS
            and t.ndim == 1
            and len(t) > 0
            and values.shape == (len(t), len(CONTROL_COLUMNS[c.kind]) - 1)
            and bool(np.all(np.abs(t) <= MAX_TIME))
            and bool(np.all(np.abs(values) <= bound))
            and not bool(np.any(np.diff(t) < 0))
            and all(a.shape == det[0].shape and a.ndim == 1 for a in det)
            and np.issubdtype(det[1].dtype, np.integer)
            and bool(np.all(np.abs(det[0].astype(float)) <= MAX_TIME))
            and bool(np.all((det[2] >= 0) & (det[2] <= MAX_POSITION)))
            and bool(np.all(np.abs(det[3]) <= math.pi))
            and not bool(np.any(np.diff(det[0]) < 0))
        )
    except (TypeError, ValueError, AttributeError):
        ok = False
    if not ok:
        validate_run(run)  # names the file and the row, as the written run would have them


def validate_run(run: RunLog, folder: str | os.PathLike | None = None) -> None:
    """Check an in-memory run against the rules the reader enforces.

    Errors name the file and the line the offending row has (or would have) in the written run:
    row i of an array is line i + 2. `folder` only prefixes the file names in messages.
    """
    base = Path(folder) if folder is not None else Path()
    check_meta(run.meta, base / RUN_JSON)
    if run.controls.kind == "wheels" and run.meta.robot is None:
        raise InputError(base / RUN_JSON, None, 'wheel-speed controls need a "robot" geometry')
    _check_controls(run.controls, base / CONTROLS_CSV)
    _check_detections(run.detections, base / DETECTIONS_CSV, run.meta.tag_map)
    if run.groundtruth is not None:
        _check_groundtruth(run.groundtruth, base / GROUNDTRUTH_CSV)
    check_time_spans(run, base)
    check_across_files(run, base)


def check_across_files(
    run: RunLog, folder: Path, names: tuple = (), lines: bool = True, sorted_rows=None
) -> None:
    """The rules of `ekfslam.plausibility` that take more than one row or one file; raise
    `InputError` naming the file and the line of the first row that breaks one.

    A hole in the controls while the robot moves; ranges and true positions too far from the
    tag map to belong to it (millimetres for metres). `names`: the three files' names (controls,
    detections, ground truth), the run format's by default; `lines`: whether row i is line
    i + 2 of its file; `sorted_rows`: per file name, the file's row of each sorted row (a
    loader that sorted), so the line is still the file's.
    """
    c_name, d_name, g_name = names or (CONTROLS_CSV, DETECTIONS_CSV, GROUNDTRUTH_CSV)

    def line(name: str, row: int) -> int | None:
        if sorted_rows is not None and name in sorted_rows:
            return sorted_rows[name](row)
        return row + 2 if lines else None

    hole = control_hole(run.controls.t, run.control_twist())
    if hole is not None:
        row, gap = hole
        before = _num(run.controls.t[row - 1])
        raise InputError(
            folder / c_name,
            line(c_name, row),
            f"no control row for {gap:.6g} s after the previous one (t {before} s) while the "
            f"robot is moving: the replay would hold that control for {gap:.6g} s; is a piece "
            "of the log missing?",
        )
    far = ranges_beyond_map(run.detections.range, run.meta.tag_map)
    if far is not None:
        row, longest = far
        raise InputError(
            folder / d_name,
            line(d_name, row),
            f"range {_num(run.detections.range[row])} m is longer than any sighting of the tag map "
            f"could be ({longest:.4g} m): millimetres for metres?",
        )
    if run.groundtruth is not None:
        far_pose = beyond_map(run.groundtruth.pose[:, :2], run.meta.tag_map)
        if far_pose is not None:
            row, distance, reach = far_pose
            xy = run.groundtruth.pose[row, :2].tolist()
            raise InputError(
                folder / g_name,
                line(g_name, row),
                f"groundtruth position {xy} is {distance:.4g} m from the tag map, beyond "
                f"{reach:.4g} m: millimetres for metres, or another map's run?",
            )
        d, g = run.detections, run.groundtruth
        truth = (g.t, g.pose)
        off = sightings_off_truth(d.t, d.tag_id, d.range, d.bearing, truth, run.meta.tag_map)
        if off is not None:
            count, compared, row = off
            raise InputError(
                folder / d_name,
                line(d_name, row),
                f"{count} of {compared} sightings do not fit the true poses of {g_name} and the "
                f"tag map (this one: range {_num(d.range[row])} m, bearing {_num(d.bearing[row])} "
                "rad): another robot's measurements mixed in, or a map in another frame?",
            )


def check_time_spans(run: RunLog, folder: Path, names: tuple = (), lines: bool = True) -> None:
    """`ekfslam.plausibility.check_clocks` on a run: detections and truth on the controls' clock.

    `names`: the three files' names (controls, detections, ground truth), the run format's by
    default; `lines` False when rows are not the files' lines (sorted, filtered, from frames).
    """
    c_name, d_name, g_name = names or (CONTROLS_CSV, DETECTIONS_CSV, GROUNDTRUTH_CSV)
    others = [(folder / d_name, run.detections.t, False)]
    if run.groundtruth is not None:
        others.append((folder / g_name, run.groundtruth.t, True))
    check_clocks((c_name, run.controls.t), others, lines)


def _check_rows(path: Path, t: Array, columns: dict[str, Array], extra=()) -> None:
    """Raise for the earliest row breaking a rule: finite values, time order, then `extra`.

    `extra` holds (mask over rows, describe(row index) -> problem) pairs.
    """
    rules: list[tuple[np.ndarray, Callable[[int], str]]] = []
    for name, values in columns.items():
        rules.append(
            (
                ~np.isfinite(values),
                lambda i, n=name, v=values: (
                    f"{n} is {_num(v[i])}: every value must be a finite number (no NaN or inf)"
                ),
            )
        )
    backwards = np.concatenate([[False], t[1:] < t[:-1]])
    rules.append(
        (
            backwards,
            lambda i: f"time {_num(t[i])} s is earlier than the previous row ({_num(t[i - 1])} s)",
        )
    )
    rules.extend(extra)
    first: tuple[int, Callable[[int], str]] | None = None
    for mask, describe in rules:
        hits = np.flatnonzero(mask)
        if hits.size and (first is None or hits[0] < first[0]):
            first = (int(hits[0]), describe)
    if first is not None:
        raise InputError(path, first[0] + 2, first[1](first[0]))


def _num(x: float) -> str:
    """The shortest text that reads back as `x` (what the writer writes): 12.4, not 12.400000001."""
    return repr(float(x))


def _check_controls(controls: Controls, path: Path) -> None:
    if controls.kind not in CONTROL_COLUMNS:
        raise InputError(path, None, f"unknown controls kind {controls.kind!r}")
    names = CONTROL_COLUMNS[controls.kind]
    check_shape(path, "controls.t", controls.t, (None,))
    check_shape(path, "controls.values", controls.values, (len(controls.t), len(names) - 1))
    if len(controls.t) == 0:
        raise InputError(path, 2, "no controls: the file has a header but no rows")
    columns = {"t": controls.t} | {n: controls.values[:, j] for j, n in enumerate(names[1:])}
    bounds = {"t": (MAX_TIME, "s", "a time")} | {n: _CONTROL_BOUNDS[n] for n in names[1:]}
    _check_rows(path, controls.t, columns, _bounded(columns, bounds))


#: column -> (the largest plausible |value|, its unit, what it is), for the messages
_CONTROL_BOUNDS = {
    **{w: (MAX_WHEEL_SPEED, "rad/s", "a wheel speed") for w in ("w1", "w2", "w3", "w4")},
    "vx": (MAX_SPEED, "m/s", "a speed"),
    "vy": (MAX_SPEED, "m/s", "a speed"),
    "wz": (MAX_TURN_RATE, "rad/s", "a turn rate"),
}


def _bounded(columns: dict[str, Array], bounds: dict[str, tuple[float, str, str]]) -> list:
    """`_check_rows` rules: each column within its plausible bound (a finite 1e300 is a corrupt
    cell, not a measurement; in seconds, a time in nanoseconds is beyond `MAX_TIME`)."""
    rules = []
    for name, (bound, unit, what) in bounds.items():
        values = columns[name]
        hint = " (nanoseconds?)" if name == "t" else ""
        rules.append(
            (
                np.abs(values) > bound,
                lambda i, n=name, v=values, b=bound, u=unit, w=what, h=hint: (
                    f"{n} {_num(v[i])} {u} is not plausible as {w} (beyond {b:g} {u}){h}"
                ),
            )
        )
    return rules


def _check_detections(det: Detections, path: Path, tag_map: dict[int, Array] | None) -> None:
    m = len(det.t)
    for name in DETECTION_COLUMNS:
        check_shape(path, f"detections.{name}", getattr(det, name), (m,))
    if not np.issubdtype(np.asarray(det.tag_id).dtype, np.integer):
        raise InputError(path, None, f"detections.tag_id must be integers, not {det.tag_id.dtype}")
    if (det.sigma_range is None) != (det.sigma_bearing is None):
        raise InputError(path, None, "give both sigma_range and sigma_bearing, or neither")
    sigmas = {}
    if det.has_sigmas:
        for name in SIGMA_COLUMNS:
            check_shape(path, f"detections.{name}", getattr(det, name), (m,))
            sigmas[name] = getattr(det, name)
    extra = [
        (det.range < 0, lambda i: f"negative range {_num(det.range[i])} m (a range is >= 0)"),
        (
            np.abs(det.bearing) > math.pi,
            lambda i: (
                f"bearing {_num(det.bearing[i])} rad is outside [-pi, pi] (degrees by mistake?)"
            ),
        ),
    ]
    for name, values in sigmas.items():  # a NaN is the finite check's, below
        extra.append(
            (
                values <= 0,
                lambda i, n=name, v=values: (
                    f"{n} {_num(v[i])} is not positive (a sighting's noise is > 0; leave the "
                    "columns out to use the replay's)"
                ),
            )
        )
    if tag_map is not None:
        known = np.array(sorted(tag_map), dtype=np.int64)
        shown = ", ".join(map(str, known[:20])) + (", ..." if len(known) > 20 else "") or "none"
        extra.append(
            (
                ~np.isin(det.tag_id, known),
                lambda i: f"tag {int(det.tag_id[i])} is not in run.json's tag_map (known: {shown})",
            )
        )
    columns = {"t": det.t, "range": det.range, "bearing": det.bearing} | sigmas
    # times: the clock check (`check_time_spans`) names both files of a run on two clocks
    extra += _bounded(columns, {"range": (MAX_POSITION, "m", "a range")})
    _check_rows(path, det.t, columns, extra)


def _check_groundtruth(gt: GroundTruth, path: Path) -> None:
    check_shape(path, "groundtruth.t", gt.t, (None,))
    check_shape(path, "groundtruth.pose", gt.pose, (len(gt.t), 3))
    if len(gt.t) == 0:
        raise InputError(path, 2, "no ground-truth rows (delete the file if there is no truth)")
    names = GROUNDTRUTH_COLUMNS[1:]
    columns = {"t": gt.t} | {n: gt.pose[:, j] for j, n in enumerate(names)}
    bounds = {  # times: the clock check names both files of a run on two clocks
        "x": (MAX_POSITION, "m", "a position"),
        "y": (MAX_POSITION, "m", "a position"),
    }
    theta = gt.pose[:, 2]
    degrees = (
        np.abs(theta) > MAX_HEADING,
        lambda i: (
            f"theta {_num(theta[i])} rad is beyond ±2π (degrees by mistake, or a heading never "
            "wrapped?); give the heading in radians, in [-π, π)"
        ),
    )
    _check_rows(path, gt.t, columns, [*_bounded(columns, bounds), degrees])


# ---------------------------------------------------------------------------------------------
# Writing


def write_run(
    run: RunLog,
    folder: str | os.PathLike,
    *,
    overwrite: bool = False,
    with_detections: bool = True,
    overwrite_hint: str = "overwrite=True",
    decimals: int | None = None,
) -> Path:
    """Write `run` as a run folder that `read_run` reads back bit for bit; returns the folder.

    The run is validated first (`validate_run`), so nothing is written for an invalid run. The
    output is deterministic: same run, same bytes. An existing non-empty folder is refused unless
    `overwrite` is True; then the run files are replaced (a stale groundtruth.csv is removed)
    and any other file in the folder is left alone. `with_detections` False leaves
    detections.csv out (and removes a stale one): a run logged as camera frames, whose
    detections ``python -m ekfslam detect`` makes; it needs ``run.meta.frames``.
    `overwrite_hint` is how the refusal tells the caller to overwrite (a command line passes
    its flag, "--overwrite").

    `decimals` rounds every float of the CSVs to that many decimals before writing (run.json is
    written as given). `read_run` then gives back the rounded values bit for bit, and writing
    those again gives the same bytes. Simulators pass `SIMULATED_DECIMALS`, so that their files
    do not depend on the CPU's vector unit; None writes every float exactly.
    """
    checks.instance(run, RunLog, "write_run: run", _RUN_HINT)
    folder = checks.path(folder, "write_run: folder")
    for name, value in (("overwrite", overwrite), ("with_detections", with_detections)):
        checks.flag(value, f"write_run: {name}")
    if decimals is not None:
        checks.whole(decimals, "write_run: decimals", lo=0, hi=17)
    validate_run(run)
    if not with_detections and run.meta.frames is None:
        raise InputError(folder / RUN_JSON, None, "a run without detections.csv needs frames")
    c, d, g = run.controls, run.detections, run.groundtruth
    texts = {
        RUN_JSON: meta_json(run.meta),
        CONTROLS_CSV: csv_text(CONTROL_COLUMNS[c.kind], [c.t, *np.asarray(c.values).T], decimals),
    }
    if with_detections:
        texts[DETECTIONS_CSV] = _detections_text(d, decimals)
    if g is not None:
        texts[GROUNDTRUTH_CSV] = csv_text(
            GROUNDTRUTH_COLUMNS, [g.t, *np.asarray(g.pose).T], decimals
        )
    if folder.exists() and not folder.is_dir():
        raise InputError(folder, None, "exists and is not a folder; choose another output path")
    if folder.is_dir() and any(folder.iterdir()) and not overwrite:
        raise InputError(
            folder,
            None,
            "folder exists and is not empty; refusing to overwrite it "
            f"(choose a new folder, or pass {overwrite_hint} to replace its run files)",
        )
    probe_output(folder, folder=True)
    with new_folder(folder):  # removed again if the writing fails or is interrupted
        # every file to a temporary one first, then all renamed at once: an interrupted write
        # leaves the old run or the new one, never half of each
        atomic_write_all({folder / name: _text_writer(text) for name, text in texts.items()})
        if g is None:
            (folder / GROUNDTRUTH_CSV).unlink(missing_ok=True)
        if not with_detections:
            (folder / DETECTIONS_CSV).unlink(missing_ok=True)
    return folder


def _text_writer(text: str) -> Callable[[Path], object]:
    return lambda tmp: tmp.write_text(text, encoding="utf-8", newline="\n")


def write_detections(
    detections: Detections, path: str | os.PathLike, tag_map: dict[int, Array] | None = None
) -> Path:
    """Write detections.csv alone (validated against `tag_map`), e.g. for a run of camera frames."""
    path = Path(path)
    _check_detections(detections, path, tag_map)
    return atomic_write_all({path: _text_writer(_detections_text(detections))})[0]


def _detections_text(d: Detections, decimals: int | None = None) -> str:
    """detections.csv's text: four columns, six when the sightings carry their own σ."""
    columns = [d.t, d.tag_id, d.range, d.bearing]
    if d.has_sigmas:
        columns += [d.sigma_range, d.sigma_bearing]
    return csv_text(
        DETECTION_LAYOUTS["detections with noise" if d.has_sigmas else "detections"],
        columns,
        decimals,
    )
