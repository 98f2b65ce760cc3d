"""What to read from a ROS bag and how to turn it into a run: `RosbagSpec` and its checks.

`ekfslam.logs.rosbag` reads the bag; this module says which topics it reads, how the camera sits
on the robot, and how a TF child frame names a tag (`RosbagSpec.tag_frame_pattern`). The spec is
checked when it is made, before a bag is opened: a pattern whose group 1 could match letters is
refused here (`check_tag_frame_pattern` walks the pattern's parsed form), not on the first
transform deep inside the bag.
"""

from __future__ import annotations

import re
import re._constants as _re_constants  # the parsed form of a pattern, to check its group 1
import re._parser as _re_parser
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from ekfslam.core.kinematics import MecanumGeometry
from ekfslam.errors import ConfigError
from ekfslam.plausibility import implausible_pose


@dataclass(frozen=True)
class RosbagSpec:
    """What to read from a bag and how to turn it into a run.

    detections_topic : the tag poses (TFMessage or an AprilTag detection array).
    twist_topic : the body twist (Twist, TwistStamped or Odometry); or else
    wheels_topic : JointState with four wheel speeds; then wheel_joints (FL, FR, RL, RR joint
        names) and robot (the mecanum geometry) are required.
    camera_mounting : (x, y, yaw) of the camera in the robot frame, m, m, rad.
    camera_pitch : rad, positive when the camera looks down.
    camera_axes : "optical" (z forward, x right, y down: what AprilTag detectors publish) or
        "body" (x forward, y left, z up).
    tag_frame_pattern : regular expression on a TF child frame; its first group is the tag id.
    camera_frame : keep only transforms whose parent frame is this (None: any parent).
    name, nominal_start, tag_map : the run's metadata (start (x, y, θ) in m, m, rad; tag map
        {id: (x, y)} in m, or None when the true tag positions are unknown).
    """

    detections_topic: str
    twist_topic: str | None = None
    wheels_topic: str | None = None
    wheel_joints: tuple[str, str, str, str] | None = None
    robot: MecanumGeometry | None = None
    camera_mounting: tuple[float, float, float] = (0.0, 0.0, 0.0)
    camera_pitch: float = 0.0
    camera_axes: Literal["optical", "body"] = "optical"
    tag_frame_pattern: str = r"(?:tag|marker)\w*?[_:/-]?(\d+)$"
    camera_frame: str | None = None
    name: str = "rosbag"
    nominal_start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tag_map: dict[int, Any] | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        if (self.twist_topic is None) == (self.wheels_topic is None):
            raise ConfigError("give exactly one of twist_topic or wheels_topic")
        if self.wheels_topic is not None and (self.wheel_joints is None or self.robot is None):
            raise ConfigError(
                "wheel speeds need wheel_joints (FL, FR, RL, RR) and the robot geometry"
            )
        if self.wheel_joints is not None and len(self.wheel_joints) != 4:
            raise ConfigError("wheel_joints must name 4 joints: FL, FR, RL, RR")
        if self.camera_axes not in ("optical", "body"):
            raise ConfigError(f"camera_axes must be 'optical' or 'body', got {self.camera_axes!r}")
        check_tag_frame_pattern(self.tag_frame_pattern)
        for what, values in (
            ("nominal_start (--start)", self.nominal_start),
            ("camera_mounting (--camera-mounting)", self.camera_mounting),
        ):
            v = np.asarray(values, dtype=np.float64)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ConfigError(f"{what} must be 3 finite numbers (x, y, theta), got {values}")
            if problem := implausible_pose(v, what):
                raise ConfigError(problem)


def check_tag_frame_pattern(pattern: str) -> None:
    """Raise ConfigError unless `pattern` compiles and its group 1 can match only digits.

    The tag id is ``int(match.group(1))``: a pattern without a group, or whose group 1 holds
    letters (``(tag)_\\d+``), would fail on the first transform, deep inside the bag.
    """
    try:
        groups = re.compile(pattern).groups
    except re.error as err:
        problem = f"tag frame pattern {pattern!r} is not a regular expression: {err}"
        raise ConfigError(problem) from None
    if not (groups and _digits_only(_group_one(_re_parser.parse(pattern)) or [])):
        raise ConfigError(
            f"tag frame pattern {pattern!r} needs a group 1 that matches the tag id's digits, "
            r"e.g. 'tag_(\d+)$'"
        )


_C = _re_constants
_REPEATS = (_C.MAX_REPEAT, _C.MIN_REPEAT, _C.POSSESSIVE_REPEAT)


def _parts(op: Any, av: Any) -> list:
    """The sub-patterns of one parsed item (a group, a repeat, a branch, a lookaround)."""
    if op in (_C.SUBPATTERN, _C.ASSERT, _C.ASSERT_NOT, _C.ATOMIC_GROUP):
        return [av[-1]]
    return [av[2]] if op in _REPEATS else list(av[1]) if op is _C.BRANCH else []


def _group_one(items: Any) -> Any:
    """The parsed body of capturing group 1 in a `re._parser` tree, or None."""
    for op, av in items:
        if op is _C.SUBPATTERN and av[0] == 1:
            return av[-1]
        for found in (_group_one(part) for part in _parts(op, av)):
            if found is not None:
                return found
    return None


def _digits_only(items: Any) -> bool:
    """Whether a parsed pattern matches only (at least one) digits."""

    def digit(op: Any, av: Any) -> bool:
        if op is _C.RANGE:
            return all(chr(k).isdigit() for k in range(av[0], av[1] + 1))
        return (op is _C.LITERAL and chr(av).isdigit()) or av is _C.CATEGORY_DIGIT

    def ok(op: Any, av: Any) -> bool:
        if op is _C.IN:
            return all(digit(o, a) for o, a in av)
        if op in _REPEATS:
            return av[0] >= 1 and _digits_only(av[2])
        if op in (_C.SUBPATTERN, _C.BRANCH):
            return all(_digits_only(part) for part in _parts(op, av))
        return digit(op, av)

    return bool(items) and all(ok(op, av) for op, av in items)
