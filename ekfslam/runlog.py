"""The run-log format: what a robot (real or simulated) records, and how ekfslam reads it back.

A run is a folder::

    run.json          format version, units, rates, robot, camera mounting, nominal start, tag map
    controls.csv      time + wheel speeds (w1..w4) or body twist (vx, vy, wz); header says which
    detections.csv    time, tag id, range, bearing (robot frame)
    groundtruth.csv   optional: time, x, y, theta

The format is specified, with units and an example, in ``data/README.md``. The reader validates
strictly and raises `ekfslam.errors.InputError` naming the file, the line and the problem.
The writer prints every float with ``repr`` (shortest round-trip), so ``read_run`` gives back
the very same bits that ``write_run`` was given.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, NoReturn

import numpy as np
from numpy.typing import NDArray

from ekfslam.errors import InputError
from ekfslam.kinematics import MecanumGeometry, wheels_to_twist

FORMAT = "ekfslam-run"
FORMAT_VERSION = 1
SUPPORTED_VERSIONS = (1,)
UNITS = {"length": "m", "angle": "rad", "time": "s"}

RUN_JSON, CONTROLS_CSV = "run.json", "controls.csv"
DETECTIONS_CSV, GROUNDTRUTH_CSV = "detections.csv", "groundtruth.csv"
CONTROL_COLUMNS = {"wheels": ("t", "w1", "w2", "w3", "w4"), "twist": ("t", "vx", "vy", "wz")}
DETECTION_COLUMNS = ("t", "tag_id", "range", "bearing")
GROUNDTRUTH_COLUMNS = ("t", "x", "y", "theta")

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Controls:
    """Commanded (or measured) motion, one row per sample, held until the next row's time.

    t : (N,) seconds, non-decreasing.
    kind : "wheels" -> values (N, 4) wheel speeds w1..w4 in rad/s (order FL, FR, RL, RR, see
           `ekfslam.kinematics`); "twist" -> values (N, 3) body twist vx, vy (m/s), wz (rad/s).
    """

    t: Array
    kind: Literal["wheels", "twist"]
    values: Array

    def twist(self, geometry: MecanumGeometry | None = None) -> Array:
        """(N, 3) body twist (vx, vy, ωz) in m/s, m/s, rad/s, whatever the kind.

        The twist is what the motion model integrates (seed eq. 4); wheel speeds are mapped through
        `ekfslam.kinematics.wheels_to_twist` and so need the robot's `geometry`.
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
    """

    t: Array
    tag_id: NDArray[np.int64]
    range: Array
    bearing: Array


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """True poses: t (K,) s and pose (K, 3) as (x, y, θ) in m, m, rad."""

    t: Array
    pose: Array


@dataclass(frozen=True, eq=False)
class RunMeta:
    """Everything in run.json.

    name : a short label for tables and plots.
    source : "simulated" or "recorded".
    control_rate_hz, camera_rate_hz : nominal rates (None when irregular or unknown).
    robot : the mecanum geometry (needed when controls are wheel speeds), or None.
    camera_mounting : (x, y, yaw) of the camera in the robot frame, m, m, rad.
    nominal_start : (3,) the pose the filter starts from (x, y, θ).
    tag_map : {tag id: (x, y)} of the known true tags, or None when unknown.
    simulation : for simulated runs, {"seed": int, "true_start": [x, y, θ], "noise": {...}, ...}.
    """

    name: str
    source: Literal["simulated", "recorded"]
    nominal_start: Array
    control_rate_hz: float | None = None
    camera_rate_hz: float | None = None
    robot: MecanumGeometry | None = None
    camera_mounting: Array = field(default_factory=lambda: np.zeros(3))
    tag_map: dict[int, Array] | None = None
    simulation: dict | None = None


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


def read_run(folder: str | os.PathLike) -> RunLog:
    """Read and validate a run folder (see ``data/README.md``).

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
    for name in (RUN_JSON, CONTROLS_CSV, DETECTIONS_CSV):
        if not (folder / name).is_file():
            raise InputError(folder / name, None, f"missing file; a run folder holds {_FILES_HINT}")
    meta = _read_meta(folder / RUN_JSON)

    path = folder / CONTROLS_CSV
    kind, columns = _read_csv(path, CONTROL_COLUMNS)
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
    _, (t, tag_id, rng, bearing) = _read_csv(path, {"detections": DETECTION_COLUMNS})
    detections = Detections(t=t, tag_id=tag_id, range=rng, bearing=bearing)
    _check_detections(detections, path, meta.tag_map)

    groundtruth = None
    path = folder / GROUNDTRUTH_CSV
    if path.exists():
        _, columns = _read_csv(path, {"groundtruth": GROUNDTRUTH_COLUMNS})
        groundtruth = GroundTruth(t=columns[0], pose=np.column_stack(columns[1:]))
        _check_groundtruth(groundtruth, path)
    return RunLog(meta=meta, controls=controls, detections=detections, groundtruth=groundtruth)


_FILES_HINT = (
    "run.json, controls.csv, detections.csv and optionally groundtruth.csv (data/README.md)"
)


def _read_lines(path: Path) -> list[str]:
    """The file's lines without BOM, line endings or trailing blank lines."""
    try:
        data = path.read_bytes()
    except OSError as err:
        raise InputError(path, None, f"cannot read the file: {err.strerror}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise InputError(path, line, f"not UTF-8 text (byte {err.start}); save as UTF-8") from None
    lines = text.removeprefix("\ufeff").splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    return lines


def _read_csv(path: Path, layouts: dict[str, tuple[str, ...]]) -> tuple[str, list[np.ndarray]]:
    """Check the header against `layouts` and parse the rows: (layout name, one array per column).

    The fast path parses the whole table at once; on any failure the rows are re-scanned one by
    one so that the error names the first bad line.
    """
    lines = _read_lines(path)
    expected = " or ".join(repr(",".join(cols)) for cols in layouts.values())
    if not lines:
        raise InputError(path, 1, f"empty file: expected the header {expected} on line 1")
    header = tuple(f.strip() for f in lines[0].split(","))
    matches = [name for name, cols in layouts.items() if cols == header]
    if not matches:
        raise InputError(
            path, 1, _header_problem(header, layouts) + f"; expected header {expected}"
        )
    name, columns = matches[0], layouts[matches[0]]
    body = lines[1:]
    if not body:
        return name, [np.empty(0, np.int64 if c == "tag_id" else np.float64) for c in columns]
    dtype = [(c, np.int64 if c == "tag_id" else np.float64) for c in columns]
    try:
        # numpy's C parser is ~10x faster than float() per cell; it skips blank lines silently,
        # hence the row count check
        table = np.loadtxt(body, dtype=dtype, delimiter=",", comments=None, ndmin=1)
        if len(table) != len(body):
            raise ValueError("blank line")
    except (ValueError, OverflowError) as err:
        _scan_rows(path, body, columns)
        raise InputError(path, None, f"cannot parse the rows: {err}") from None
    return name, [np.ascontiguousarray(table[c]) for c in columns]


def _parse_cell(column: str, text: str) -> None:
    """Raise ValueError unless `text` is a plain ASCII number (an integer for tag_id)."""
    if not text.isascii() or "_" in text:  # float() also takes "1_000" and Arabic digits
        raise ValueError(text)
    if column != "tag_id":
        float(text)
    elif not -(2**63) <= int(text) < 2**63:
        raise OverflowError(text)


def _header_problem(header: tuple[str, ...], layouts: dict[str, tuple[str, ...]]) -> str:
    closest = max(layouts.values(), key=lambda cols: len(set(cols) & set(header)))
    missing = [c for c in closest if c not in header]
    unknown = [c for c in header if c not in closest]
    parts = [f"missing column {', '.join(missing)}"] if missing else []
    parts += [f"unknown column {', '.join(map(repr, unknown))}"] if unknown else []
    return f"header {','.join(header)!r}: " + (
        "; ".join(parts) or "columns repeated or out of order"
    )


def _scan_rows(path: Path, body: list[str], columns: tuple[str, ...]) -> None:
    """Raise InputError for the first row that does not parse (the slow, precise path)."""
    for number, line in enumerate(body, start=2):
        fields = [f.strip() for f in line.split(",")]
        if not line.strip():
            raise InputError(path, number, "blank line in the middle of the file")
        if fields[0] == "t":
            raise InputError(
                path,
                number,
                "header line repeated in the middle of the file (two logs pasted together?)",
            )
        if len(fields) != len(columns):
            raise InputError(
                path,
                number,
                f"expected {len(columns)} fields ({','.join(columns)}), "
                f"found {len(fields)} (truncated line?)",
            )
        for column, text in zip(columns, fields, strict=True):
            try:
                _parse_cell(column, text)
            except (ValueError, OverflowError):
                what = "an integer" if column == "tag_id" else "a number"
                raise InputError(path, number, f"{column} is not {what}: {text!r}") from None


# ---------------------------------------------------------------------------------------------
# Validation (shared by reader and writer)


def validate_run(run: RunLog, folder: str | os.PathLike | None = None) -> None:
    """Check an in-memory run against the rules the reader enforces.

    Errors name the file and the line the offending row has (or would have) in the written run:
    row i of an array is line i + 2. `folder` only prefixes the file names in messages.
    """
    base = Path(folder) if folder is not None else Path()
    _check_meta(run.meta, base / RUN_JSON)
    if run.controls.kind == "wheels" and run.meta.robot is None:
        raise InputError(base / RUN_JSON, None, 'wheel-speed controls need a "robot" geometry')
    _check_controls(run.controls, base / CONTROLS_CSV)
    _check_detections(run.detections, base / DETECTIONS_CSV, run.meta.tag_map)
    if run.groundtruth is not None:
        _check_groundtruth(run.groundtruth, base / GROUNDTRUTH_CSV)


def _check_shape(path: Path, what: str, array: np.ndarray, shape: tuple[int | None, ...]) -> None:
    a = np.asarray(array)
    if a.ndim != len(shape) or any(
        s is not None and s != n for s, n in zip(shape, a.shape, strict=False)
    ):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise InputError(path, None, f"{what} has shape {a.shape}, expected {want}")


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
    _check_shape(path, "controls.t", controls.t, (None,))
    _check_shape(path, "controls.values", controls.values, (len(controls.t), len(names) - 1))
    if len(controls.t) == 0:
        raise InputError(path, 2, "no controls: the file has a header but no rows")
    columns = {"t": controls.t} | {n: controls.values[:, j] for j, n in enumerate(names[1:])}
    _check_rows(path, controls.t, columns)


def _check_detections(det: Detections, path: Path, tag_map: dict[int, Array] | None) -> None:
    m = len(det.t)
    for name in DETECTION_COLUMNS:
        _check_shape(path, f"detections.{name}", getattr(det, name), (m,))
    if not np.issubdtype(np.asarray(det.tag_id).dtype, np.integer):
        raise InputError(path, None, f"detections.tag_id must be integers, not {det.tag_id.dtype}")
    extra = [
        (det.range < 0, lambda i: f"negative range {_num(det.range[i])} m (a range is >= 0)"),
        (
            np.abs(det.bearing) > math.pi,
            lambda i: (
                f"bearing {_num(det.bearing[i])} rad is outside [-pi, pi] (degrees by mistake?)"
            ),
        ),
    ]
    if tag_map is not None:
        known = np.array(sorted(tag_map), dtype=np.int64)
        shown = ", ".join(map(str, known[:20])) + (", ..." if len(known) > 20 else "") or "none"
        extra.append(
            (
                ~np.isin(det.tag_id, known),
                lambda i: f"tag {int(det.tag_id[i])} is not in run.json's tag_map (known: {shown})",
            )
        )
    _check_rows(path, det.t, {"t": det.t, "range": det.range, "bearing": det.bearing}, extra)


def _check_groundtruth(gt: GroundTruth, path: Path) -> None:
    _check_shape(path, "groundtruth.t", gt.t, (None,))
    _check_shape(path, "groundtruth.pose", gt.pose, (len(gt.t), 3))
    if len(gt.t) == 0:
        raise InputError(path, 2, "no ground-truth rows (delete the file if there is no truth)")
    names = GROUNDTRUTH_COLUMNS[1:]
    _check_rows(path, gt.t, {"t": gt.t} | {n: gt.pose[:, j] for j, n in enumerate(names)})


def _check_meta(meta: RunMeta, path: Path) -> None:
    def require(ok: bool, problem: str) -> None:
        if not ok:
            raise InputError(path, None, problem)

    require(isinstance(meta.name, str) and bool(meta.name), "name must be a non-empty string")
    require(meta.source in ("simulated", "recorded"), 'source must be "simulated" or "recorded"')
    for what, value, n in (
        ("nominal_start", meta.nominal_start, 3),
        ("camera_mounting", meta.camera_mounting, 3),
    ):
        _check_shape(path, what, value, (n,))
        require(bool(np.all(np.isfinite(value))), f"{what} must be {n} finite numbers")
    for what, rate in (("controls_hz", meta.control_rate_hz), ("camera_hz", meta.camera_rate_hz)):
        require(rate is None or (math.isfinite(rate) and rate > 0), f"{what} must be > 0 or null")
    require(
        meta.robot is None or isinstance(meta.robot, MecanumGeometry),
        "robot must be a MecanumGeometry or None",
    )
    for tag, xy in (meta.tag_map or {}).items():
        require(isinstance(tag, int | np.integer), f"tag_map id {tag!r} is not an integer")
        _check_shape(path, f"tag_map[{tag}]", xy, (2,))
        require(bool(np.all(np.isfinite(xy))), f"tag_map[{tag}] must be 2 finite numbers")
    try:
        _dump_json(meta.simulation, indent=2)
    except (TypeError, ValueError) as err:
        raise InputError(path, None, f"simulation is not plain JSON data: {err}") from None


# ---------------------------------------------------------------------------------------------
# run.json

_REQUIRED_KEYS = tuple(
    "format format_version name source units camera_mounting nominal_start".split()
)
_OPTIONAL_KEYS = ("rates", "robot", "tag_map", "simulation")  # absent means null


class _JsonProblem(Exception):
    def __init__(self, token: str, problem: str, occurrence: int = 0) -> None:
        super().__init__(problem)
        self.token, self.problem, self.occurrence = token, problem, occurrence


def _no_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict:
    seen: dict[str, Any] = {}
    for key, value in pairs:
        if key in seen:
            raise _JsonProblem(f'"{key}"', f"key {key!r} appears twice", occurrence=1)
        seen[key] = value
    return seen


def _no_constants(name: str) -> float:
    raise _JsonProblem(name, f"{name} is not allowed: every number must be finite")


def _line_of(text: str, token: str, occurrence: int = 0) -> int | None:
    """1-based line of the `occurrence`-th appearance of `token` (a best effort for messages)."""
    hits = [m.start() for m in re.finditer(re.escape(token), text)]
    return text.count("\n", 0, hits[occurrence]) + 1 if len(hits) > occurrence else None


def _read_meta(path: Path) -> RunMeta:
    text = "\n".join(_read_lines(path))
    try:
        doc = json.loads(text, object_pairs_hook=_no_duplicate_keys, parse_constant=_no_constants)
    except json.JSONDecodeError as err:
        raise InputError(
            path, err.lineno, f"invalid JSON: {err.msg} (column {err.colno})"
        ) from None
    except _JsonProblem as err:
        raise InputError(path, _line_of(text, err.token, err.occurrence), err.problem) from None

    def fail(key: str | None, problem: str) -> NoReturn:
        raise InputError(path, _line_of(text, f'"{key}"') if key else None, problem)

    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        found = repr(doc.get("format")) if isinstance(doc, dict) else "not a JSON object"
        fail("format", f'not an ekfslam run: "format" is {found}, expected "{FORMAT}"')
    version = doc.get("format_version")
    if type(version) is not int or version not in SUPPORTED_VERSIONS:
        supported = ", ".join(map(str, SUPPORTED_VERSIONS))
        fail(
            "format_version",
            f"format_version {version!r} is not supported; "
            f"this ekfslam reads format_version {supported}",
        )
    for key in doc:
        if key not in _REQUIRED_KEYS + _OPTIONAL_KEYS:
            fail(
                key,
                f"unknown key {key!r}; run.json keys are {', '.join(_REQUIRED_KEYS)}, "
                f"{', '.join(_OPTIONAL_KEYS)}",
            )
    for key in _REQUIRED_KEYS:
        if key not in doc:
            fail(None, f"missing key {key!r}")
    if doc["units"] != UNITS:
        fail(
            "units",
            f"unknown units {json.dumps(doc['units'])}: ekfslam reads only "
            f"{json.dumps(UNITS)}; convert the data (e.g. degrees to radians) first",
        )
    if not isinstance(doc["name"], str) or not doc["name"]:
        fail("name", '"name" must be a non-empty string')
    if doc["source"] not in ("simulated", "recorded"):
        fail("source", f'"source" is {doc["source"]!r}, expected "simulated" or "recorded"')

    def numbers(key: str, value: Any, n: int, what: str) -> Array:
        ok = isinstance(value, list) and len(value) == n and all(_is_number(v) for v in value)
        if not ok:
            fail(key, f"{what} must be {n} finite numbers, got {json.dumps(value)}")
        return np.array(value, dtype=np.float64)

    def fields(key: str, value: Any, names: tuple[str, ...], optional: bool) -> dict:
        if value is None and optional:
            return {}
        if not isinstance(value, dict) or not set(value) <= set(names):
            fail(key, f'"{key}" must be an object with keys {", ".join(names)}')
        if not optional and set(value) != set(names):
            fail(key, f'"{key}" must have all of the keys {", ".join(names)}')
        return value

    def positive(key: str, value: Any, what: str, nullable: bool) -> float | None:
        if value is None and nullable:
            return None
        if not _is_number(value) or value <= 0:
            fail(key, f"{what} must be a positive number{' or null' if nullable else ''}")
        return float(value)

    rates = fields("rates", doc.get("rates"), ("controls_hz", "camera_hz"), optional=True)
    robot = None
    if doc.get("robot") is not None:
        spec = fields("robot", doc["robot"], ("type", "wheel_radius", "lx", "ly"), optional=False)
        if spec["type"] != "mecanum":
            fail("robot", f'robot type {spec["type"]!r} is not supported; only "mecanum" is')
        robot = MecanumGeometry(
            **{k: positive(k, spec[k], f"robot {k}", False) for k in ("wheel_radius", "lx", "ly")}
        )
    mount = fields("camera_mounting", doc["camera_mounting"], ("x", "y", "yaw"), optional=False)
    tag_map = None
    if doc.get("tag_map") is not None:
        if not isinstance(doc["tag_map"], dict):
            fail("tag_map", '"tag_map" must be an object {"<id>": [x, y], ...} or null')
        tag_map = {}
        for key, xy in doc["tag_map"].items():
            if not re.fullmatch(r"[+-]?[0-9]+", key):
                fail(key, f"tag_map id {key!r} is not an integer")
            if int(key) in tag_map:
                fail(key, f"tag_map id {int(key)} appears twice")
            tag_map[int(key)] = numbers(key, xy, 2, f"tag_map entry {key!r}")
    simulation = doc.get("simulation")
    if simulation is not None and not isinstance(simulation, dict):
        fail("simulation", '"simulation" must be an object or null')
    return RunMeta(
        name=doc["name"],
        source=doc["source"],
        nominal_start=numbers(
            "nominal_start", doc["nominal_start"], 3, "nominal_start [x, y, theta]"
        ),
        control_rate_hz=positive("controls_hz", rates.get("controls_hz"), "controls_hz", True),
        camera_rate_hz=positive("camera_hz", rates.get("camera_hz"), "camera_hz", True),
        robot=robot,
        camera_mounting=numbers(
            "camera_mounting", [mount[k] for k in ("x", "y", "yaw")], 3, "camera_mounting x, y, yaw"
        ),
        tag_map=tag_map,
        simulation=simulation,
    )


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _plain(value: Any) -> Any:
    """json.dumps hook: numpy scalars and arrays become plain numbers and lists."""
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON data")


def _dump_json(value: Any, indent: int | None = None) -> str:
    separators = (",", ": ") if indent else (", ", ": ")
    return json.dumps(
        value,
        sort_keys=True,
        allow_nan=False,
        default=_plain,
        indent=indent,
        separators=separators,
        ensure_ascii=False,
    )


def _meta_json(meta: RunMeta) -> str:
    """run.json text: fixed key order, one key per line, tag_map sorted by id, floats by repr."""
    robot = None
    if meta.robot is not None:
        r = meta.robot
        robot = {"type": "mecanum", "wheel_radius": r.wheel_radius, "lx": r.lx, "ly": r.ly}
    x, y, yaw = np.asarray(meta.camera_mounting, dtype=np.float64).tolist()
    entries = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "name": meta.name,
        "source": meta.source,
        "units": UNITS,
        "rates": {"controls_hz": meta.control_rate_hz, "camera_hz": meta.camera_rate_hz},
        "robot": robot,
        "camera_mounting": {"x": x, "y": y, "yaw": yaw},
        "nominal_start": np.asarray(meta.nominal_start, dtype=np.float64).tolist(),
    }
    lines = [f'  "{key}": {_dump_json(value)}' for key, value in entries.items()]
    if meta.tag_map is None:
        lines.append('  "tag_map": null')
    else:
        tags = [
            f'    "{int(k)}": {_dump_json(np.asarray(meta.tag_map[k], dtype=np.float64))}'
            for k in sorted(meta.tag_map)
        ]
        lines.append('  "tag_map": {' + ("\n" + ",\n".join(tags) + "\n  " if tags else "") + "}")
    simulation = _dump_json(meta.simulation, indent=2).replace("\n", "\n  ")
    lines.append(f'  "simulation": {simulation}')
    return "{\n" + ",\n".join(lines) + "\n}\n"


# ---------------------------------------------------------------------------------------------
# Writing


def write_run(run: RunLog, folder: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Write `run` as a run folder that `read_run` reads back bit for bit; returns the folder.

    The run is validated first (`validate_run`), so nothing is written for an invalid run. The
    output is deterministic: same run, same bytes. An existing non-empty folder is refused unless
    `overwrite` is True; then the run files are replaced (a stale groundtruth.csv is removed)
    and any other file in the folder is left alone.
    """
    folder = Path(folder)
    validate_run(run)
    c, d, g = run.controls, run.detections, run.groundtruth
    texts = {
        RUN_JSON: _meta_json(run.meta),
        CONTROLS_CSV: _csv_text(CONTROL_COLUMNS[c.kind], [c.t, *np.asarray(c.values).T]),
        DETECTIONS_CSV: _csv_text(DETECTION_COLUMNS, [d.t, d.tag_id, d.range, d.bearing]),
    }
    if g is not None:
        texts[GROUNDTRUTH_CSV] = _csv_text(GROUNDTRUTH_COLUMNS, [g.t, *np.asarray(g.pose).T])
    if folder.exists() and not folder.is_dir():
        raise InputError(folder, None, "exists and is not a folder; choose another output path")
    if folder.is_dir() and any(folder.iterdir()) and not overwrite:
        raise InputError(
            folder,
            None,
            "folder exists and is not empty; refusing to overwrite it "
            "(choose a new folder, or pass overwrite=True to replace its run files)",
        )
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in texts.items():
        # write-then-rename, so an interrupted write never leaves half a file under the real name
        temporary = folder / f".{name}.partial"
        temporary.write_text(text, encoding="utf-8", newline="\n")
        os.replace(temporary, folder / name)
    if g is None:
        (folder / GROUNDTRUTH_CSV).unlink(missing_ok=True)
    return folder


def _csv_text(columns: tuple[str, ...], arrays: list[np.ndarray]) -> str:
    # tolist() gives Python floats/ints, whose repr is the shortest text that reads back exactly
    cells = [np.asarray(a).tolist() for a in arrays]
    rows = [",".join(map(repr, row)) for row in zip(*cells, strict=True)]
    return "\n".join([",".join(columns), *rows]) + "\n"
