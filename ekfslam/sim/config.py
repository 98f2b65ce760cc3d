"""What a simulation is: `SimulationConfig`, and the name of the run it makes.

A run's name says what was simulated ("octagon-2laps" for one of the seed's experiments,
`SEED_EXPERIMENTS`, else with what differs); recognising the seed's experiments from a run's
``simulation`` block (`seed_experiment`) is the same knowledge, so it lives here too, and the
scoring (`ekfslam.analysis.evaluation`) asks this module rather than the other way round.
`REALISTIC` lists the systematic errors of a real classroom robot, each with its value and why.
`ekfslam.sim.simulation` runs a config and re-exports these names.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.camera import (
    DEFAULT_MOUNTING,
    TAG_HEIGHT,
    TAG_SIZE,
    Camera,
    TagSpec,
    pinhole_camera,
)
from ekfslam.core.kinematics import MecanumGeometry
from ekfslam.errors import ConfigError
from ekfslam.fieldtypes import field_types

Array = NDArray[np.float64]

TRAJECTORIES = ("square", "octagon")
#: The fields of a real robot's systematic errors; at their defaults the robot is ideal.
SYSTEMATIC_FIELDS = (
    "tag_position_sigma",
    "range_scale",
    "wheel_radius_scale",
    "wheelbase_scale",
    "slip_fraction",
    "camera_latency",
    "motor_lag",
    "lens_distortion_ignored",
    "camera_yaw_error",
)
DEFAULT_SIZE = 0.75  # m: the seed's square side (and octagon size), 1.5 m arena


@dataclass(frozen=True)
class SimulationConfig:
    """Every setting of a simulated run, with the defaults used throughout the course.

    Path
        trajectory : "square" or "octagon" (see `waypoints`).  size : m (0.75).  laps : (2).
    Randomness
        seed : the one seed of every random draw (0).
    Rates
        controls_hz : wheel commands and ground truth, Hz (20).  camera_hz : camera frames, Hz (10).
    Controller (acts on the believed pose)
        max_speed : m/s (0.15).  max_turn_rate : rad/s (0.8).  max_accel : m/s² (0.5).
        max_angular_accel : rad/s² (4.0).  heading_gain : 1/s (2.0), proportional heading
        correction while driving.  stop_duration : s (1.0) at rest after the last waypoint.
    Robot
        robot : the mecanum geometry (`MecanumGeometry()`).
    Motion noise, drawn per control interval and per wheel, only while the robot is commanded to
    move (a robot at rest does not creep)
        wheel_noise_sigma : rad/s (0.3).  wheel_noise_fraction : extra std as a fraction of the
        commanded wheel speed (0.03); the two add in quadrature.  wheel_scale_sigma : std of a
        per-run, per-wheel scale error (a radius miscalibration) as a fraction (0.0, off because the
        seed's filter models white noise only; turn it on for systematic drift).
    Placement error (true start = nominal start + error)
        start_error : explicit (dx, dy, dθ) in m, m, rad, or None to draw it (None).
        start_error_sigma : std of the drawn error (0.03 m, 0.03 m, 0.08 rad); the seed's Table 1
        reports offsets of 2-6 cm and 0.14 rad.
    Camera (the one the frames runs are rendered with; see `ekfslam.core.camera.tags_in_view`)
        camera : the pinhole camera, intrinsics, distortion, height and pitch
        (`ekfslam.core.camera.pinhole_camera()`: 640x480, 65° horizontal field of view, mild barrel
        distortion, 12 cm above the floor, level).  camera_mounting : its (x, y, yaw) in the
        robot frame, m, m, rad (6 cm ahead of the centre, facing forward).  tag_size : side of
        the tags' black squares, m (0.16).  tag_height : height of the tags' centres, m (0.15).
        view_margin_px : how far inside the image the tag's outline must stay, px (1.0).
        camera_min_range, camera_max_range : m from the robot centre (0.1, 2.0).
        max_incidence : largest angle between a tag's normal and the line of sight for the tag
        to be read, rad (75°, the angle beyond which `ekfslam.vision.detect` refuses a tag).
    Detection noise
        range_noise_sigma : m (0.02).  range_noise_fraction : extra std as a fraction of the range
        (0.0); in quadrature.  bearing_noise_sigma : rad (0.02).  dropout : probability that a
        visible tag is missed in a frame (0.1).
    Systematic errors of a real robot (default off: the ideal robot; `REALISTIC` below gives
    the values a classroom robot has, and why)
        tag_position_sigma : std of each tag's true position about its tag_map entry, per axis,
        m (0.0): the tags were placed, and the map measured, by hand.  range_scale : the
        camera's distance to a tag is reported this many times too long, along the line of
        sight from the camera (1.0): a focal length or tag size that is off.
        wheel_radius_scale : true wheel radius / the nominal one in run.json (1.0).
        wheelbase_scale : true lx + ly / the nominal one (1.0): how far the rollers' contact
        points are from the centre.  slip_fraction : mean fraction of the wheels' motion lost
        to slip while moving, drawn per control interval uniform in [0, 2 slip_fraction] (0.0).
        camera_latency : s from a frame's exposure to its time stamp (0.0): a detection is
        stamped later than the robot was where it saw the tag.  motor_lag : s, the time
        constant of a first-order lag between the commanded wheel speeds (controls.csv) and
        the wheels' real speeds (0.0).  lens_distortion_ignored : how much of the camera's
        radial distortion (k1, k2) the detector leaves in its ranges and bearings, 0 to 1 (0.0;
        1: it never undistorts, so off-axis tags read long and towards the image centre).
        camera_yaw_error : rad, how far the camera really points left of the robot's heading,
        which its detections take it to face (0.0).
    Outliers (default off)
        outlier_wrong_id_rate : probability that a detection reports another tag's id, one not
        otherwise reported in that frame (0.0).  outlier_range_rate : probability that its range
        is multiplied or divided (equally likely) by U(1.5, 3) (0.0).
    """

    trajectory: str = "square"
    size: float = DEFAULT_SIZE
    laps: int = 2
    seed: int = 0
    controls_hz: float = 20.0
    camera_hz: float = 10.0
    max_speed: float = 0.15
    max_turn_rate: float = 0.8
    max_accel: float = 0.5
    max_angular_accel: float = 4.0
    heading_gain: float = 2.0
    stop_duration: float = 1.0
    robot: MecanumGeometry = field(default_factory=MecanumGeometry)
    wheel_noise_sigma: float = 0.3
    wheel_noise_fraction: float = 0.03
    wheel_scale_sigma: float = 0.0
    start_error: tuple[float, float, float] | None = None
    start_error_sigma: tuple[float, float, float] = (0.03, 0.03, 0.08)
    camera: Camera = field(default_factory=pinhole_camera)
    camera_mounting: tuple[float, float, float] = DEFAULT_MOUNTING
    tag_size: float = TAG_SIZE
    tag_height: float = TAG_HEIGHT
    view_margin_px: float = 1.0
    camera_min_range: float = 0.1
    camera_max_range: float = 2.0
    max_incidence: float = math.radians(75.0)
    range_noise_sigma: float = 0.02
    range_noise_fraction: float = 0.0
    bearing_noise_sigma: float = 0.02
    dropout: float = 0.1
    outlier_wrong_id_rate: float = 0.0
    outlier_range_rate: float = 0.0
    tag_position_sigma: float = 0.0
    range_scale: float = 1.0
    wheel_radius_scale: float = 1.0
    wheelbase_scale: float = 1.0
    slip_fraction: float = 0.0
    camera_latency: float = 0.0
    motor_lag: float = 0.0
    lens_distortion_ignored: float = 0.0
    camera_yaw_error: float = 0.0

    def __post_init__(self) -> None:
        field_types(self)
        if self.trajectory not in TRAJECTORIES:
            raise ConfigError(f"trajectory must be one of {TRAJECTORIES}, got {self.trajectory!r}")
        for name in ("start_error", "start_error_sigma", "camera_mounting"):  # lists -> tuples
            value = getattr(self, name)
            if value is not None:
                if len(value) != 3 or not all(math.isfinite(float(v)) for v in value):
                    raise ConfigError(f"SimulationConfig.{name} is 3 finite numbers, got {value!r}")
                object.__setattr__(self, name, tuple(float(v) for v in value))
        if not isinstance(self.camera, Camera) or self.camera.mount_height is None:
            raise ConfigError("SimulationConfig.camera must be a Camera with its mount_height set")
        rules = (
            ("laps", lambda v: v == int(v) >= 1, "a positive whole number"),
            (
                "size controls_hz camera_hz max_speed max_turn_rate max_accel max_angular_accel "
                "tag_size tag_height camera_max_range max_incidence range_scale wheel_radius_scale "
                "wheelbase_scale",
                lambda v: v > 0,
                "positive",
            ),
            (
                "heading_gain stop_duration wheel_noise_sigma wheel_noise_fraction "
                "wheel_scale_sigma camera_min_range range_noise_sigma range_noise_fraction "
                "bearing_noise_sigma "
                "view_margin_px tag_position_sigma camera_latency motor_lag",
                lambda v: v >= 0,
                "zero or positive",
            ),
            ("seed", lambda v: 0 <= v < 2**63, "a whole number from 0 to 2^63 - 1"),
            ("slip_fraction", lambda v: 0 <= v <= 0.5, "a fraction in [0, 0.5]"),
            ("lens_distortion_ignored", lambda v: 0 <= v <= 1, "a fraction in [0, 1]"),
            ("camera_yaw_error", lambda v: abs(v) < 0.5, "an angle under 0.5 rad"),
            ("start_error_sigma", lambda v: min(v) >= 0, "zero or positive"),
            (
                "dropout outlier_wrong_id_rate outlier_range_rate",
                lambda v: 0 <= v <= 1,
                "a probability in [0, 1]",
            ),
        )
        for names, ok, what in rules:
            for name in names.split():
                if not ok(getattr(self, name)):
                    raise ConfigError(
                        f"SimulationConfig.{name} must be {what}, got {getattr(self, name)!r}"
                    )
        object.__setattr__(self, "laps", int(self.laps))

    @property
    def name(self) -> str:
        """The run's name, from what was simulated (`run_name`)."""
        return run_name(self)

    @property
    def tags(self) -> TagSpec:
        """The printed tags (`tag_size`)."""
        return TagSpec(self.tag_size)

    def to_dict(self) -> dict[str, Any]:
        """Every field as plain JSON types (robot and camera as dicts, tuples as lists).

        The systematic errors (`SYSTEMATIC_FIELDS`) appear only when they are not ideal, so a
        run made before they existed is written, and recognised, unchanged.
        """
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in SYSTEMATIC_FIELDS and value == f.default:
                continue
            if isinstance(value, MecanumGeometry | Camera):
                value = {
                    k: list(v) if isinstance(v, tuple) else v
                    for k, v in dataclasses.asdict(value).items()
                }
            elif isinstance(value, tuple):
                value = list(value)
            out[f.name] = value
        return out


def config_from_dict(data: dict[str, Any]) -> SimulationConfig:
    """The inverse of `SimulationConfig.to_dict`; missing keys take their defaults.

    A config written before the simulator had a camera model names only ``camera_fov`` (rad,
    the horizontal field of view); it becomes the default camera with that field of view.
    """
    data = dict(data)
    fov = data.pop("camera_fov", None)
    if fov is not None and "camera" not in data:
        data["camera"] = pinhole_camera(horizontal_fov_deg=math.degrees(fov))
    known = {f.name for f in dataclasses.fields(SimulationConfig)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(
            f"unknown SimulationConfig fields {unknown}; known fields: {sorted(known)}"
        )
    kwargs = dict(data)
    if isinstance(kwargs.get("robot"), dict):
        kwargs["robot"] = MecanumGeometry(**kwargs["robot"])
    if isinstance(kwargs.get("camera"), dict):
        kwargs["camera"] = Camera(**kwargs["camera"])
    for name in ("start_error", "start_error_sigma"):
        if kwargs.get(name) is not None:
            kwargs[name] = tuple(kwargs[name])
    return SimulationConfig(**kwargs)


@dataclass(frozen=True)
class ErrorSource:
    """One systematic error of a real robot: the `SimulationConfig` field, its value, and why
    a student can defend that value."""

    field: str
    value: float
    why: str


#: The realistic robot: the error sources a classroom robot has, each with a defensible value.
#: `SimulationConfig(**REALISTIC_ERRORS)` turns them all on; `ekfslam.sim.scenarios.realistic`
#: builds the seed's experiments with them, and `ekfslam.analysis.error_budget` weighs each.
REALISTIC: dict[str, ErrorSource] = {
    "tag placement": ErrorSource(
        "tag_position_sigma",
        0.03,
        "tags taped to the walls by hand and their map taken with a tape measure: 2-3 cm "
        "per coordinate",
    ),
    "range scale": ErrorSource(
        "range_scale",
        1.09,
        "the distance z = f S / s_px twice off: a focal length taken from the webcam's "
        "datasheet field of view instead of a calibration (3-5 % long) and tags printed "
        '"fit to page", 3-6 % smaller than the S the detector is told (1.05 x 1.04)',
    ),
    "lens distortion": ErrorSource(
        "lens_distortion_ignored",
        1.0,
        "the same uncalibrated camera has no distortion coefficients to undo, so its mild "
        "barrel distortion (k1 = -0.08) is left in: tags off to the side read up to 5 % long "
        "and 1° towards the image centre",
    ),
    "camera yaw": ErrorSource(
        "camera_yaw_error",
        0.05,
        "a webcam clamped to the chassis and aimed by eye, its optical axis taken as the "
        "image centre: 2-4° off the robot's heading (0.05 rad, 3°)",
    ),
    "wheel radius": ErrorSource(
        "wheel_radius_scale",
        0.985,
        "the nominal 30 mm radius against the real rollers' rolling radius, read with a "
        "ruler to half a millimetre, and the rubber flattens under the robot: 1-2 % smaller",
    ),
    "wheelbase": ErrorSource(
        "wheelbase_scale",
        0.97,
        "mecanum rollers touch the floor off the wheels' centre planes, so the effective "
        "lx + ly differs from the ruler's (taken to the wheels' outer faces) by 2-4 %",
    ),
    "wheel slip": ErrorSource(
        "slip_fraction",
        0.02,
        "mecanum rollers on a smooth classroom floor lose a few % of the motion, at random",
    ),
    "motor lag": ErrorSource(
        "motor_lag",
        0.3,
        "controls.csv holds the commanded wheel speeds, and small gear motors reach a new "
        "speed in a few tenths of a second: MRCLAM's robots lag their commands by 0.25-0.30 s",
    ),
    "camera latency": ErrorSource(
        "camera_latency",
        0.3,
        "a USB webcam buffers a frame or two (0.1-0.2 s at 10 Hz) and the tag detector on a "
        "small computer takes about 0.1 s: 0.2-0.3 s from exposure to time stamp",
    ),
}
REALISTIC_ERRORS: dict[str, float] = {s.field: s.value for s in REALISTIC.values()}

#: The seed's two experiments as data/runs/generate.sh simulates them: two laps of each path,
#: with fixed seeds and placement errors of the size the seed's Table 1 reports. Their replays
#: are the ones compared with the seed's real-robot row (`seed_experiment`).
SEED_EXPERIMENTS: dict[str, dict[str, Any]] = {
    "square-2laps": dict(trajectory="square", laps=2, seed=1, start_error=(-0.02, 0.05, 0.14)),
    "octagon-2laps": dict(trajectory="octagon", laps=2, seed=2, start_error=(-0.04, 0.04, 0.13)),
}


def same_experiment(config: dict[str, Any] | None, kwargs: dict[str, Any] | None) -> bool:
    """Whether a config dict (`SimulationConfig.to_dict`, or as read back from run.json) is
    the `SimulationConfig(**kwargs)` experiment, every field compared.

    Numbers agree to a relative 1e-4, so a run.json written with fewer digits still counts.
    """
    if config is None or kwargs is None:
        return False
    try:
        wanted = SimulationConfig(**kwargs).to_dict()
    except (TypeError, ValueError):
        return False
    return _close(config, wanted)


def _close(a: Any, b: Any) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, bool | str | None) or isinstance(b, bool | str | None):
        return a == b
    try:
        return math.isclose(float(a), float(b), rel_tol=1e-4, abs_tol=1e-12)
    except (TypeError, ValueError):
        return False


def run_name(config: SimulationConfig) -> str:
    """A simulated run's name: "octagon-2laps" for one of `SEED_EXPERIMENTS` (the shipped
    data/runs), else with what differs, e.g. "octagon-2laps-seed5-size0.6-start0.02,0,-0.1-
    wheelscale0.01" (the seed, and any non-default size, start error, wheel scale), so that no
    other run is mistaken for the seed's."""
    c = config
    base = f"{c.trajectory}-{c.laps}lap{'s' if c.laps != 1 else ''}"
    if same_experiment(c.to_dict(), SEED_EXPERIMENTS.get(base)):
        return base
    parts = [base, f"seed{c.seed}"]
    if c.size != DEFAULT_SIZE:
        parts.append(f"size{c.size:g}")
    if c.start_error is not None:
        parts.append("start" + ",".join(f"{v:g}" for v in c.start_error))
    if c.wheel_scale_sigma != 0.0:
        parts.append(f"wheelscale{c.wheel_scale_sigma:g}")
    systematic = {k: v for k, v in c.to_dict().items() if k in SYSTEMATIC_FIELDS}
    if systematic:
        ideal = dataclasses.replace(c, **{k: getattr(SimulationConfig, k) for k in systematic})
        realistic = systematic == REALISTIC_ERRORS
        if realistic and same_experiment(ideal.to_dict(), SEED_EXPERIMENTS.get(base)):
            return f"{base}-realistic"  # the seed's experiment on the realistic robot
        parts.append("realistic" if realistic else "systematic")
    return "-".join(parts)


def seed_experiment(simulation: dict[str, Any] | None) -> str | None:
    """The trajectory ("square" / "octagon") if a run is one of the seed's experiments, else None.

    Decided by the run's ``simulation.config`` (run.json), not by its name: a run renamed, or
    a different run named like one, is judged by what was simulated. The seed's experiment
    driven by the realistic robot (`REALISTIC_ERRORS`, "square-2laps-realistic") counts too:
    it is the same experiment on a robot like the seed's.
    """
    config = (simulation or {}).get("config")
    if not isinstance(config, dict):
        return None
    systematic = {k: config[k] for k in SYSTEMATIC_FIELDS if k in config}
    if systematic:
        if not _close(systematic, REALISTIC_ERRORS):
            return None
        config = {k: v for k, v in config.items() if k not in systematic}
    for kwargs in SEED_EXPERIMENTS.values():
        if same_experiment(config, kwargs):
            return str(kwargs["trajectory"])
    return None
