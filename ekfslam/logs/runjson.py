"""run.json: the metadata of a run (format, robot, camera, tag map, frames), read and written.

`ekfslam.logs.runlog` reads and writes the whole run folder; this module holds the one JSON file's
schema: the `RunMeta` dataclass (with the camera intrinsics, the printed tag size and the frames of
a run logged as camera frames), its reader (one `InputError` naming the line of the first
problem), its checks, and its deterministic writer. The JSON text itself (no duplicate keys, no
NaN, bounded integers and nesting, line numbers, sorted keys) is `ekfslam.logs.jsonsafe`'s. The
keys are documented in ``data/README.md``; all the camera keys are optional, so
``format_version`` stays 1.
"""

from __future__ import annotations

import json
import math
import os
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, NoReturn

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.camera import Camera, TagSpec
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.kinematics import MecanumGeometry
from ekfslam.core.noise import NoiseConfig
from ekfslam.errors import InputError
from ekfslam.logs import realistic_defaults
from ekfslam.logs.csvtable import read_lines
from ekfslam.logs.jsonsafe import dump_json, is_number, line_of, load_json, shown
from ekfslam.logs.mrclam import defaults as mrclam_defaults
from ekfslam.plausibility import beyond_map, coincident
from ekfslam.plausibility import implausible_pose as _implausible

FORMAT = "ekfslam-run"
FORMAT_VERSION = 1
SUPPORTED_VERSIONS = (1,)
UNITS = {"length": "m", "angle": "rad", "time": "s"}

Array = NDArray[np.float64]

#: The tuned defaults a loader can name in `RunMeta.defaults`: name -> (noise, filter choices).
#: A dataset's loader owns its values (`ekfslam.logs.mrclam.defaults`); run.json keeps the name.
TUNED_DEFAULTS: dict[str, tuple[NoiseConfig, FilterConfig]] = {
    mrclam_defaults.NAME: (mrclam_defaults.MRCLAM_NOISE, mrclam_defaults.MRCLAM_CONFIG),
    realistic_defaults.NAME: realistic_defaults.DEFAULTS,
}


@dataclass(frozen=True)
class FramesSpec:
    """Where a run's camera frames are, relative to the run folder.

    kind : "video" (one file OpenCV can read, e.g. ``frames.mp4``) or "images" (one file per
        frame, named by a printf pattern such as ``frames/%06d.png``).
    file : the video's file name, or the image pattern with one integer field (the frame index).

    ``frames.csv`` gives each frame's time and index (``t,frame``); see `ekfslam.logs.frames`.
    """

    kind: Literal["video", "images"]
    file: str

    def __post_init__(self) -> None:
        if self.kind not in ("video", "images"):
            raise ValueError(f'FramesSpec.kind must be "video" or "images", got {self.kind!r}')
        if not isinstance(self.file, str) or not self.file or Path(self.file).is_absolute():
            raise ValueError("FramesSpec.file must be a relative path inside the run folder")
        if ".." in Path(self.file).parts:
            raise ValueError("FramesSpec.file must stay inside the run folder (no '..')")
        if self.kind == "images" and len(re.findall(r"%0?\d*d", self.file)) != 1:
            raise ValueError("an image pattern needs one integer field, e.g. frames/%06d.png")

    def path(self, index: int) -> str:
        """The file of frame `index` (for "images"), or the video file."""
        return self.file % index if self.kind == "images" else self.file


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
    camera : intrinsics, distortion, mounting height and pitch (`ekfslam.core.camera.Camera`), or
        None.
    tags : the printed tags' family and size (`ekfslam.core.camera.TagSpec`), or None.
    frames : where the camera frames are (`FramesSpec`), or None for a run without frames.
    defaults : the name of the tuned noise and filter choices its loader chose for it (a key of
        `TUNED_DEFAULTS`: "mrclam" for MRCLAM runs, "realistic" for the simulator's realistic
        robot), or None for `NoiseConfig()` and `FilterConfig()`; see `noise_defaults`,
        `filter_defaults`.
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
    camera: Camera | None = None
    tags: TagSpec | None = None
    frames: FramesSpec | None = None
    defaults: str | None = None

    @property
    def noise_defaults(self) -> NoiseConfig | None:
        """The loader's tuned noise for this run, or None (then `NoiseConfig()` applies)."""
        return None if self.defaults is None else TUNED_DEFAULTS[self.defaults][0]

    @property
    def filter_defaults(self) -> FilterConfig | None:
        """The loader's filter choices for this run, or None (then `FilterConfig()` applies)."""
        return None if self.defaults is None else TUNED_DEFAULTS[self.defaults][1]


def check_shape(path: Path, what: str, array: np.ndarray, shape: tuple[int | None, ...]) -> None:
    """Raise `InputError` (naming `path`) unless `array` has `shape` (None: any length)."""
    a = np.asarray(array)
    if a.ndim != len(shape) or any(
        s is not None and s != n for s, n in zip(shape, a.shape, strict=False)
    ):
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
        raise InputError(path, None, f"{what} has shape {a.shape}, expected {want}")


def check_meta(meta: RunMeta, path: Path) -> None:
    """The rules `read_meta` enforces, for an in-memory `RunMeta` (errors name `path`)."""

    def require(ok: bool, problem: str) -> None:
        if not ok:
            raise InputError(path, None, problem)

    require(isinstance(meta.name, str) and bool(meta.name), "name must be a non-empty string")
    require(meta.source in ("simulated", "recorded"), 'source must be "simulated" or "recorded"')
    for what, value, n in (
        ("nominal_start", meta.nominal_start, 3),
        ("camera_mounting", meta.camera_mounting, 3),
    ):
        check_shape(path, what, value, (n,))
        require(bool(np.all(np.isfinite(value))), f"{what} must be {n} finite numbers")
        problem = _implausible(value, what, pose=True)
        require(problem is None, str(problem))
    for what, rate in (("controls_hz", meta.control_rate_hz), ("camera_hz", meta.camera_rate_hz)):
        require(rate is None or (math.isfinite(rate) and rate > 0), f"{what} must be > 0 or null")
    require(
        meta.robot is None or isinstance(meta.robot, MecanumGeometry),
        "robot must be a MecanumGeometry or None",
    )
    for tag, xy in (meta.tag_map or {}).items():
        require(isinstance(tag, int | np.integer), f"tag_map id {tag!r} is not an integer")
        check_shape(path, f"tag_map[{tag}]", xy, (2,))
        require(bool(np.all(np.isfinite(xy))), f"tag_map[{tag}] must be 2 finite numbers")
        problem = _implausible(xy, f"tag_map[{tag}]", pose=False)
        require(problem is None, str(problem))
    try:
        dump_json(meta.simulation, indent=2)
    except (TypeError, ValueError) as err:
        raise InputError(path, None, f"simulation is not plain JSON data: {err}") from None
    require(meta.camera is None or isinstance(meta.camera, Camera), "camera must be a Camera")
    require(meta.tags is None or isinstance(meta.tags, TagSpec), "tags must be a TagSpec")
    require(meta.frames is None or isinstance(meta.frames, FramesSpec), "frames: FramesSpec")
    require(meta.defaults is None or meta.defaults in TUNED_DEFAULTS, _DEFAULTS_PROBLEM)
    if meta.tag_map:
        problem, _ = _map_problem(meta.tag_map)
        require(problem is None, str(problem))
        far = _start_problem(np.asarray(meta.nominal_start, dtype=float), meta.tag_map)
        require(far is None, str(far))
    require(
        meta.frames is None or (meta.camera is not None and meta.tags is not None),
        'a run with "frames" needs "camera" (intrinsics) and "tags" (the printed size)',
    )


# ---------------------------------------------------------------------------------------------
# Reading

_REQUIRED_KEYS = tuple(
    "format format_version name source units camera_mounting nominal_start".split()
)
_OPTIONAL_KEYS = ("rates", "robot", "tag_map", "simulation", "camera", "tags", "frames", "defaults")
_DEFAULTS_PROBLEM = f"defaults must be one of {', '.join(map(repr, TUNED_DEFAULTS))} or null"
# absent means null; camera, tags and frames are the camera-frame extension (ekfslam.logs.frames)
_CAMERA_KEYS = ("image_size", "fx", "fy", "cx", "cy", "distortion", "mount_height", "pitch")
_CAMERA_REQUIRED = ("image_size", "fx", "fy", "cx", "cy")


def read_meta(path: str | os.PathLike) -> RunMeta:
    """Read and check run.json at `path`; `InputError` names the line of the first problem."""
    path = Path(path)
    text = "\n".join(read_lines(path))
    doc = load_json(text, path, "run metadata")

    def fail(key: str | None, problem: str) -> NoReturn:
        raise InputError(path, line_of(text, f'"{key}"') if key else None, problem)

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

    def numbers(key: str, value: Any, n: int, what: str, pose: bool = False) -> Array:
        ok = isinstance(value, list) and len(value) == n and all(is_number(v) for v in value)
        if not ok:
            fail(key, f"{what} must be {n} finite numbers, got {shown(value)}")
        array = np.array(value, dtype=np.float64)
        problem = _implausible(array, what, pose)
        if problem:
            fail(key, problem)
        return array

    def number(key: str, value: Any, what: str) -> float:
        if not is_number(value):
            fail(key, f"{what} must be a finite number, got {json.dumps(value)}")
        return float(value)

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
        if not is_number(value) or value <= 0:
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
            if len(key.lstrip("+-").lstrip("0")) > 19 or not -(2**63) <= int(key) < 2**63:
                fail(key, f"tag_map id {key[:40]} is too large (an id must fit in 64 bits)")
            if int(key) in tag_map:
                fail(key, f"tag_map id {int(key)} appears twice")
            tag_map[int(key)] = numbers(key, xy, 2, f"tag_map entry {key!r}")
    simulation = doc.get("simulation")
    if simulation is not None and not isinstance(simulation, dict):
        fail("simulation", '"simulation" must be an object or null')
    camera = tags = frames = None
    if doc.get("camera") is not None:
        spec = fields("camera", doc["camera"], _CAMERA_KEYS, optional=True)
        missing = [k for k in _CAMERA_REQUIRED if k not in spec]
        if missing:
            fail("camera", f'"camera" is missing {", ".join(missing)}')
        size = spec["image_size"]
        if not (isinstance(size, list) and len(size) == 2 and all(_is_count(v) for v in size)):
            fail("image_size", '"image_size" must be [width, height] in whole pixels')
        dist = spec.get("distortion", [0.0] * 5)
        if not (isinstance(dist, list) and len(dist) in (4, 5) and all(map(is_number, dist))):
            fail("distortion", '"distortion" must be [k1, k2, p1, p2] or [k1, k2, p1, p2, k3]')
        camera = Camera(
            *size,
            *(positive(k, spec[k], f"camera {k} (px)", False) for k in ("fx", "fy")),
            *(number(k, spec[k], f"camera {k} (px)") for k in ("cx", "cy")),
            distortion=tuple(dist),
            mount_height=positive(
                "mount_height", spec.get("mount_height"), "camera mount_height (m)", True
            ),
            pitch=number("pitch", spec.get("pitch", 0.0), "camera pitch (rad)"),
        )
    if doc.get("tags") is not None:
        spec = fields("tags", doc["tags"], ("family", "size"), optional=False)
        if spec["family"] != "tag36h11":
            fail("tags", f'tag family {spec["family"]!r} is not supported; only "tag36h11" is')
        tags = TagSpec(positive("size", spec["size"], "tags size (m)", False), spec["family"])
    if doc.get("frames") is not None:
        spec = fields("frames", doc["frames"], ("kind", "file"), optional=False)
        try:
            frames = FramesSpec(spec["kind"], spec["file"])
        except ValueError as err:
            fail("frames", f'"frames": {err}')
        if camera is None or tags is None:
            fail("frames", 'a run with "frames" needs "camera" (intrinsics) and "tags" (size)')
    defaults = doc.get("defaults")
    if defaults is not None and (not isinstance(defaults, str) or defaults not in TUNED_DEFAULTS):
        fail("defaults", f'"defaults" is {shown(defaults)}: {_DEFAULTS_PROBLEM}')
    if tag_map is not None:
        problem, pairs = _map_problem(tag_map)
        if problem is not None:
            fail("tag_map", problem)
        for a, b in pairs:
            warnings.warn(
                f"{path}:{line_of(text, f'{chr(34)}{b}{chr(34)}')}: tags {a} and {b} are at the "
                "same point in tag_map (a copy and paste?)",
                stacklevel=2,
            )
    start = numbers(
        "nominal_start", doc["nominal_start"], 3, "nominal_start [x, y, theta]", pose=True
    )
    far = _start_problem(start, tag_map)
    if far is not None:
        fail("nominal_start", far)
    return RunMeta(
        name=doc["name"],
        source=doc["source"],
        nominal_start=start,
        control_rate_hz=positive("controls_hz", rates.get("controls_hz"), "controls_hz", True),
        camera_rate_hz=positive("camera_hz", rates.get("camera_hz"), "camera_hz", True),
        robot=robot,
        camera_mounting=numbers(
            "camera_mounting",
            [mount[k] for k in ("x", "y", "yaw")],
            3,
            "camera_mounting x, y, yaw",
            pose=True,
        ),
        tag_map=tag_map,
        simulation=simulation,
        camera=camera,
        tags=tags,
        frames=frames,
        defaults=defaults,
    )


def _map_problem(tag_map: dict[int, Array]) -> tuple[str | None, list[tuple[int, int]]]:
    """Why the tag map cannot place a run (every tag at one point), and the pairs of tags at
    one point (`ekfslam.plausibility.coincident`)."""
    at_one, pairs = coincident(tag_map)
    if at_one:
        xy = np.asarray(tag_map[at_one[0]], dtype=float).tolist()
        return (
            f"tag_map: all {len(at_one)} tags are at one point {xy}: eq. (17) cannot find the "
            "map's rotation from it; give each tag its own position",
            [],
        )
    return None, pairs


def _start_problem(start: Array, tag_map: dict[int, Array] | None) -> str | None:
    far = beyond_map(np.asarray(start)[None, :2], tag_map)
    if far is None:
        return None
    _, distance, reach = far
    return (
        f"nominal_start {np.asarray(start).tolist()} is {distance:.4g} m from the tag map, beyond "
        f"{reach:.4g} m: millimetres for metres, or another map's start?"
    )


def _is_count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value > 0


def meta_json(meta: RunMeta) -> str:
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
    lines = [f'  "{key}": {dump_json(value)}' for key, value in entries.items()]
    if meta.tag_map is None:
        lines.append('  "tag_map": null')
    else:
        tags = [
            f'    "{int(k)}": {dump_json(np.asarray(meta.tag_map[k], dtype=np.float64))}'
            for k in sorted(meta.tag_map)
        ]
        lines.append('  "tag_map": {' + ("\n" + ",\n".join(tags) + "\n  " if tags else "") + "}")
    simulation = dump_json(meta.simulation, indent=2).replace("\n", "\n  ")
    lines.append(f'  "simulation": {simulation}')
    c, tags, frames = meta.camera, meta.tags, meta.frames
    # the camera extension and defaults are written only when present: older runs keep their bytes
    optional = {
        "camera": None
        if c is None
        else {
            "image_size": [c.width, c.height],
            "fx": c.fx,
            "fy": c.fy,
            "cx": c.cx,
            "cy": c.cy,
            "distortion": list(c.distortion),
            "mount_height": c.mount_height,
            "pitch": c.pitch,
        },
        "tags": None if tags is None else {"family": tags.family, "size": tags.size},
        "frames": None if frames is None else {"kind": frames.kind, "file": frames.file},
        "defaults": meta.defaults,
    }
    lines += [f'  "{k}": {dump_json(v)}' for k, v in optional.items() if v is not None]
    return "{\n" + ",\n".join(lines) + "\n}\n"
