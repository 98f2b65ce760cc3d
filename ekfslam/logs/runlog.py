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

from ekfslam.core.kinematics import MecanumGeometry, wheels_to_twist
from ekfslam.errors import InputError
from ekfslam.files import atomic_write_text
from ekfslam.logs.csvtable import csv_text, read_table
from ekfslam.logs.runjson import RunMeta, check_meta, check_shape, meta_json, read_meta
from ekfslam.plausibility import check_clocks

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
    folder = Path(folder)
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
    if path.exists():
        _, columns = read_table(path, {"groundtruth": GROUNDTRUTH_COLUMNS})
        groundtruth = GroundTruth(t=columns[0], pose=np.column_stack(columns[1:]))
        _check_groundtruth(groundtruth, path)
    run = RunLog(meta=meta, controls=controls, detections=detections, groundtruth=groundtruth)
    if found_in_frames:  # the detections' times are the frames': name the file that has them
        check_time_spans(run, folder, (CONTROLS_CSV, "frames.csv", GROUNDTRUTH_CSV), lines=False)
    else:
        check_time_spans(run, folder)
    return run


def require_file(path: Path, hint: str) -> None:
    """Raise `InputError` unless `path` is a file: missing, a folder, a dead link or a loop."""
    if not path.is_file():  # is_file() follows links: a loop or a dangling link ends here too
        problem = "is a folder, not a file" if path.is_dir() else "missing file"
        if path.is_symlink() and not path.is_dir():
            problem = "is a symbolic link that leads to no file (dangling, or a loop)"
        raise InputError(path, None, f"{problem}; {hint}")


_FILES_HINT = (
    "run.json, controls.csv, detections.csv and optionally groundtruth.csv (data/README.md)"
)


# ---------------------------------------------------------------------------------------------
# Validation (shared by reader and writer)


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
    _check_rows(path, controls.t, columns)


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
    _check_rows(path, det.t, columns, extra)


def _check_groundtruth(gt: GroundTruth, path: Path) -> None:
    check_shape(path, "groundtruth.t", gt.t, (None,))
    check_shape(path, "groundtruth.pose", gt.pose, (len(gt.t), 3))
    if len(gt.t) == 0:
        raise InputError(path, 2, "no ground-truth rows (delete the file if there is no truth)")
    names = GROUNDTRUTH_COLUMNS[1:]
    _check_rows(path, gt.t, {"t": gt.t} | {n: gt.pose[:, j] for j, n in enumerate(names)})


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
    folder = Path(folder)
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
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in texts.items():
        # write-then-rename, so an interrupted write never leaves half a file under the real name
        atomic_write_text(folder / name, text)
    if g is None:
        (folder / GROUNDTRUTH_CSV).unlink(missing_ok=True)
    if not with_detections:
        (folder / DETECTIONS_CSV).unlink(missing_ok=True)
    return folder


def write_detections(
    detections: Detections, path: str | os.PathLike, tag_map: dict[int, Array] | None = None
) -> Path:
    """Write detections.csv alone (validated against `tag_map`), e.g. for a run of camera frames."""
    path = Path(path)
    _check_detections(detections, path, tag_map)
    return atomic_write_text(path, _detections_text(detections))


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
