"""The run-log format: what a robot (real or simulated) records, and how ekfslam reads it back.

A run is a folder::

    run.json          format version, units, rates, robot, camera mounting, nominal start, tag map
    controls.csv      time + wheel speeds (w1..w4) or body twist (vx, vy, wz); header says which
    detections.csv    time, tag id, range, bearing (robot frame)
    groundtruth.csv   optional: time, x, y, theta

The format is specified, with units and an example, in ``data/README.md``. The reader validates
strictly and raises `ekfslam.errors.InputError` naming the file, the line and the problem.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from ekfslam.kinematics import MecanumGeometry

FORMAT_VERSION = 1

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
