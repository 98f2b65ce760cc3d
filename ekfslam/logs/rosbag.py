"""Convert a ROS bag from your own robot into a run log, with the `rosbags` library (no ROS needed).

Reads ROS 1 ``.bag`` files and ROS 2 bag folders (sqlite3 or mcap) through
`rosbags.highlevel.AnyReader`. Two topics are needed:

Motion, one of
    ``geometry_msgs/Twist``, ``geometry_msgs/TwistStamped`` or ``nav_msgs/Odometry`` (its
    ``twist.twist``): the body twist (vx, vy, ωz) of eq. (4), e.g. ``/cmd_vel`` or ``/odom``;
    ``sensor_msgs/JointState``: four wheel speeds (rad/s) of a mecanum robot, picked by joint name
    in the order FL, FR, RL, RR (`ekfslam.core.kinematics`); the robot geometry must be given.

Tag sightings, one of
    ``tf2_msgs/TFMessage`` (``/tf``): every transform whose child frame matches
    `RosbagSpec.tag_frame_pattern` (default ``tag_7``, ``tag7``, ``tag36h11:7``, ``marker_7``...)
    and, if `RosbagSpec.camera_frame` is set, whose parent is that frame;
    an AprilTag detection array with poses (``apriltag_ros/AprilTagDetectionArray`` of ROS 1,
    ``isaac_ros_apriltag_interfaces/AprilTagDetectionArray`` of ROS 2): each detection's
    ``pose.pose.pose.position``. Bundles (several ids in one detection) are skipped and counted.

A tag's position p in the camera frame becomes a range and bearing from the robot's centre: p is
rotated out of the camera frame (OpenCV's optical axes, z forward, x right, y down, unless
`RosbagSpec.camera_axes` is "body": x forward, y left, z up), pitched and yawed by the camera
mounting, shifted by the camera's (x, y) on the robot, and then (r, φ) = (‖p_xy‖, atan2(p_y, p_x)),
the measurement of eq. (10).

Times are the messages' header stamps where they have one (the sensor's clock), else the time the
bag recorded them. ROS ``Twist`` has no header, so its times are the bag's. What to read (the
topics, the camera mounting, the tag-frame pattern) is a `RosbagSpec` (`ekfslam.logs.rosbag_spec`).
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ekfslam.errors import InputError
from ekfslam.files import not_a_file
from ekfslam.geometry import wrap_angle
from ekfslam.logs.rosbag_spec import RosbagSpec
from ekfslam.logs.runlog import Controls, Detections, RunLog, RunMeta

TWIST_TYPES = ("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped", "nav_msgs/msg/Odometry")
WHEEL_TYPES = ("sensor_msgs/msg/JointState",)
TF_TYPES = ("tf2_msgs/msg/TFMessage",)
#: Detection arrays are recognised by the end of their type name and must carry poses.
DETECTION_ARRAY_SUFFIX = "/AprilTagDetectionArray"


@dataclass(frozen=True)
class RosbagReport:
    """What `read_rosbag` read and left out; nothing is dropped without being counted.

    motion_messages : rows of controls.  detection_messages : messages on the detections topic.
    detections_kept : tag sightings that became detections.
    frames_skipped : TF transforms that are not a tag (child frame does not match) or not from
        the camera frame.  bundles_skipped : detections with several ids.
    at_camera_skipped : sightings within 1 mm of the robot's centre (no bearing).
    bag_stamps_used : messages timed by the bag because they have no header (or a zero stamp).
    """

    motion_messages: int
    detection_messages: int
    detections_kept: int
    frames_skipped: int
    bundles_skipped: int
    at_camera_skipped: int
    bag_stamps_used: int


def read_rosbag(
    paths: str | os.PathLike | Sequence[str | os.PathLike], spec: RosbagSpec
) -> tuple[RunLog, RosbagReport]:
    """Read a ROS 1 or ROS 2 bag into a `RunLog` (and a `RosbagReport`).

    Parameters
    ----------
    paths : a ROS 2 bag folder, or one or more ROS 1 ``.bag`` files (read as one recording).
    spec : the topics and the camera mounting, see `RosbagSpec`.

    Returns
    -------
    (RunLog, RosbagReport)
        Controls (twist or wheels), detections (t, tag id, range m, bearing rad in [-π, π)),
        both sorted by time; no ground truth. meta.source is "recorded".

    Raises
    ------
    InputError
        The bag is missing or unreadable, a topic is absent (the message lists the bag's topics),
        a topic has an unsupported type, or a topic holds no usable messages.
    """
    # lazy: rosbags takes 0.06 s to import and only reading a bag needs it
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore  # lazy: as above

    paths = [Path(paths)] if isinstance(paths, str | os.PathLike) else [Path(p) for p in paths]
    if not paths:
        raise InputError(Path(), None, "no bag given")
    first = paths[0]
    for path in paths:
        if not path.exists():
            raise InputError(path, None, "bag not found (a ROS 1 .bag file or a ROS 2 bag folder)")
        if path.is_dir() and not (path / "metadata.yaml").exists():
            raise InputError(
                path,
                None,
                "not a ROS 2 bag: the folder has no metadata.yaml (a ROS 1 bag is a .bag file)",
            )
        for file in [path / "metadata.yaml"] if path.is_dir() else [path]:
            problem = not_a_file(file)  # a FIFO would block the reader for ever
            if problem is not None:
                raise InputError(file, None, f"{problem}; a bag is read from regular files")
    motion_topic = spec.twist_topic or spec.wheels_topic
    try:
        with AnyReader(paths, default_typestore=get_typestore(Stores.LATEST)) as reader:
            topics = {c.topic: c.msgtype for c in reader.connections}
            for topic in (motion_topic, spec.detections_topic):
                if topic not in topics:
                    listing = ", ".join(f"{t} ({m})" for t, m in sorted(topics.items())) or "none"
                    raise InputError(first, None, f"topic {topic} not in the bag; it has {listing}")
            _check_types(first, spec, topics)
            motion = _Motion(spec, topics[motion_topic], first)
            sightings = _Sightings(spec, topics[spec.detections_topic])
            wanted = [
                c for c in reader.connections if c.topic in (motion_topic, spec.detections_topic)
            ]
            for connection, bag_ns, raw in reader.messages(connections=wanted):
                msg = reader.deserialize(raw, connection.msgtype)
                if connection.topic == motion_topic:
                    motion.add(msg, bag_ns)
                else:
                    sightings.add(msg, bag_ns)
    except InputError:
        raise
    except (AnyReaderError, OSError) as exc:
        raise InputError(first, None, f"cannot read the bag: {exc}") from None
    except Exception as exc:  # a damaged bag fails anywhere inside rosbags, sqlite3 or yaml
        raise InputError(
            first, None, f"cannot read the bag (damaged?): {type(exc).__name__}: {exc}"
        ) from None

    if not motion.t:
        raise InputError(first, None, f"no messages on {motion_topic}")
    controls = motion.controls()
    detections, at_camera = sightings.detections()
    meta = RunMeta(
        name=spec.name,
        source="recorded",
        nominal_start=np.asarray(spec.nominal_start, dtype=np.float64),
        robot=spec.robot,
        camera_mounting=np.asarray(spec.camera_mounting, dtype=np.float64),
        tag_map=None
        if spec.tag_map is None
        else {int(k): np.asarray(v, dtype=np.float64) for k, v in spec.tag_map.items()},
    )
    report = RosbagReport(
        motion_messages=len(motion.t),
        detection_messages=sightings.messages,
        detections_kept=len(detections.t),
        frames_skipped=sightings.frames_skipped,
        bundles_skipped=sightings.bundles_skipped,
        at_camera_skipped=at_camera,
        bag_stamps_used=motion.bag_stamps + sightings.bag_stamps,
    )
    return RunLog(meta=meta, controls=controls, detections=detections), report


def _check_types(path: Path, spec: RosbagSpec, topics: dict[str, str]) -> None:
    if spec.twist_topic is not None and topics[spec.twist_topic] not in TWIST_TYPES:
        raise InputError(
            path,
            None,
            f"{spec.twist_topic} is {topics[spec.twist_topic]}; a twist topic must be one of "
            + ", ".join(TWIST_TYPES),
        )
    if spec.wheels_topic is not None and topics[spec.wheels_topic] not in WHEEL_TYPES:
        raise InputError(
            path, None, f"{spec.wheels_topic} is {topics[spec.wheels_topic]}, not JointState"
        )
    kind = topics[spec.detections_topic]
    if kind not in TF_TYPES and not kind.endswith(DETECTION_ARRAY_SUFFIX):
        raise InputError(
            path,
            None,
            f"{spec.detections_topic} is {kind}; tag poses must come as tf2_msgs/TFMessage or an "
            "AprilTag detection array with poses",
        )


def _stamp(header: Any, bag_ns: int) -> tuple[float, bool]:
    """(time in s, whether the bag's time was used) for a message header (or None)."""
    if header is not None and (header.stamp.sec or header.stamp.nanosec):
        return header.stamp.sec + header.stamp.nanosec * 1e-9, False
    return bag_ns * 1e-9, True


class _Motion:
    """Collects control rows from Twist, TwistStamped, Odometry or JointState messages."""

    def __init__(self, spec: RosbagSpec, msgtype: str, path: Path) -> None:
        self.spec, self.msgtype, self.path = spec, msgtype, path
        self.t: list[float] = []
        self.rows: list[tuple[float, ...]] = []
        self.bag_stamps = 0

    def add(self, msg: Any, bag_ns: int) -> None:
        t, from_bag = _stamp(getattr(msg, "header", None), bag_ns)
        if self.msgtype == "sensor_msgs/msg/JointState":
            velocity = dict(
                zip(msg.name, np.asarray(msg.velocity, dtype=float).tolist(), strict=False)
            )
            missing = [j for j in self.spec.wheel_joints if j not in velocity]
            if missing:
                raise InputError(
                    self.path,
                    None,
                    f"{self.spec.wheels_topic}: joint(s) {', '.join(missing)} have no velocity "
                    f"at t = {t!r} s (the message names {', '.join(msg.name) or 'none'})",
                )
            row = tuple(velocity[j] for j in self.spec.wheel_joints)
        else:
            twist = {
                "geometry_msgs/msg/Twist": lambda m: m,
                "geometry_msgs/msg/TwistStamped": lambda m: m.twist,
                "nav_msgs/msg/Odometry": lambda m: m.twist.twist,
            }[self.msgtype](msg)
            row = (twist.linear.x, twist.linear.y, twist.angular.z)
        self.t.append(t)
        self.rows.append(row)
        self.bag_stamps += from_bag

    def controls(self) -> Controls:
        t = np.array(self.t)
        order = np.argsort(t, kind="stable")
        kind = "wheels" if self.spec.wheels_topic is not None else "twist"
        return Controls(t=t[order], kind=kind, values=np.array(self.rows, dtype=float)[order])


class _Sightings:
    """Collects tag positions in the camera frame from TF messages or detection arrays."""

    def __init__(self, spec: RosbagSpec, msgtype: str) -> None:
        self.spec, self.is_tf = spec, msgtype in TF_TYPES
        self.pattern = re.compile(spec.tag_frame_pattern)
        self.t: list[float] = []
        self.ids: list[int] = []
        self.points: list[tuple[float, float, float]] = []
        self.messages = self.frames_skipped = self.bundles_skipped = self.bag_stamps = 0

    def add(self, msg: Any, bag_ns: int) -> None:
        self.messages += 1
        if self.is_tf:
            for tf in msg.transforms:
                match = self.pattern.search(tf.child_frame_id.lstrip("/"))
                camera = self.spec.camera_frame
                if match is None or (
                    camera is not None and tf.header.frame_id.lstrip("/") != camera
                ):
                    self.frames_skipped += 1
                    continue
                p = tf.transform.translation
                self._keep(tf.header, bag_ns, int(match.group(1)), (p.x, p.y, p.z))
            return
        for det in msg.detections:
            ids = np.atleast_1d(np.asarray(det.id)).tolist()
            if len(ids) != 1:
                self.bundles_skipped += 1
                continue
            p = det.pose.pose.pose.position
            header = det.pose.header if det.pose.header.stamp.sec else msg.header
            self._keep(header, bag_ns, int(ids[0]), (p.x, p.y, p.z))

    def _keep(self, header: Any, bag_ns: int, tag: int, point: tuple[float, float, float]) -> None:
        t, from_bag = _stamp(header, bag_ns)
        self.t.append(t)
        self.ids.append(tag)
        self.points.append(point)
        self.bag_stamps += from_bag

    def detections(self) -> tuple[Detections, int]:
        """The sightings as range and bearing from the robot's centre, sorted by time."""
        spec = self.spec
        p = np.array(self.points, dtype=float).reshape(-1, 3)
        x, y = camera_to_robot(p, spec.camera_mounting, spec.camera_pitch, spec.camera_axes)
        rng = np.hypot(x, y)
        ok = rng > 1e-3
        order = np.argsort(np.array(self.t)[ok], kind="stable")
        det = Detections(
            t=np.array(self.t, dtype=float)[ok][order],
            tag_id=np.array(self.ids, dtype=np.int64)[ok][order],
            range=rng[ok][order],
            bearing=np.asarray(wrap_angle(np.arctan2(y[ok], x[ok])[order]), dtype=float),
        )
        return det, int(np.count_nonzero(~ok))


def camera_to_robot(
    points: np.ndarray,
    mounting: tuple[float, float, float],
    pitch: float = 0.0,
    axes: Literal["optical", "body"] = "optical",
) -> tuple[np.ndarray, np.ndarray]:
    """Points in the camera frame -> their (x, y) in the robot frame, m.

    points : (N, 3), m, in the camera's `axes` ("optical": x right, y down, z forward; "body":
        x forward, y left, z up).
    mounting : (x, y, yaw) of the camera on the robot, m, m, rad.
    pitch : rad, positive looks down: the camera's forward axis is (cos p, 0, -sin p) in the
        yawed robot frame, its up axis (sin p, 0, cos p).

    Returns x (N,) and y (N,); the height is dropped (range and bearing are planar).
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    if axes == "optical":
        forward, left, up = p[:, 2], -p[:, 0], -p[:, 1]
    else:
        forward, left, up = p[:, 0], p[:, 1], p[:, 2]
    level = forward * np.cos(pitch) + up * np.sin(pitch)  # the forward distance on the floor
    mx, my, yaw = (float(v) for v in mounting)
    c, s = np.cos(yaw), np.sin(yaw)
    return mx + c * level - s * left, my + s * level + c * left
