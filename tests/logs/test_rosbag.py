"""ROS bag conversion, on ROS 1 and ROS 2 bags that the tests write with `rosbags`.

The tag positions in the camera frame are built here from a known robot pose, camera mounting
and tag position with plain trigonometry (not with `ekfslam.core.camera`), so the range and bearing
the converter gives back can be checked against the geometry directly.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from ekfslam.cli.main import main
from ekfslam.core.kinematics import MecanumGeometry, twist_to_wheels
from ekfslam.errors import InputError
from ekfslam.logs.rosbag import read_rosbag
from ekfslam.logs.rosbag_spec import RosbagSpec
from ekfslam.logs.runlog import read_run
from ekfslam.pipeline import replay

APRILTAG_ROS = {
    "apriltag_ros/msg/AprilTagDetection": (
        "int32[] id\nfloat64[] size\ngeometry_msgs/PoseWithCovarianceStamped pose\n"
    ),
    "apriltag_ros/msg/AprilTagDetectionArray": (
        "std_msgs/Header header\napriltag_ros/AprilTagDetection[] detections\n"
    ),
}
TAGS = {3: (2.0, 0.5), 5: (0.0, 2.5), 8: (-1.5, 1.0), 11: (1.0, -1.2)}
TAG_HEIGHT = 0.25  # m above the camera: the converter must ignore it
MOUNT = (0.08, -0.02, 0.3)  # camera x, y (m) and yaw (rad) on the robot
PITCH = 0.1  # rad, looking down a little
V, W = 0.4, 0.4  # m/s, rad/s: a circle of radius 1 m


def true_pose(t: float) -> tuple[float, float, float]:
    r = V / W
    return r * math.sin(W * t), r * (1 - math.cos(W * t)), W * t


def camera_point(pose, tag_xy, axes: str = "optical") -> tuple[float, float, float]:
    """Where the tag is in the camera frame, by hand: yaw, then pitch, then the axes."""
    x, y, th = pose
    cx = x + MOUNT[0] * math.cos(th) - MOUNT[1] * math.sin(th)
    cy = y + MOUNT[0] * math.sin(th) + MOUNT[1] * math.cos(th)
    yaw = th + MOUNT[2]
    dx, dy = tag_xy[0] - cx, tag_xy[1] - cy
    forward = dx * math.cos(yaw) + dy * math.sin(yaw)
    left = -dx * math.sin(yaw) + dy * math.cos(yaw)
    up = TAG_HEIGHT
    xc = forward * math.cos(PITCH) - up * math.sin(PITCH)  # pitched down by PITCH
    zc = forward * math.sin(PITCH) + up * math.cos(PITCH)
    if axes == "body":
        return xc, left, zc
    return -left, -zc, xc  # optical: x right, y down, z forward


def true_measurement(pose, tag_xy) -> tuple[float, float]:
    x, y, th = pose
    dx, dy = tag_xy[0] - x, tag_xy[1] - y
    bearing = (math.atan2(dy, dx) - th + math.pi) % (2 * math.pi) - math.pi
    return math.hypot(dx, dy), bearing


def stamp(ts, t: float):
    sec = math.floor(t)
    return ts.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=round((t - sec) * 1e9))


def header(ts, t: float, frame: str):
    H = ts.types["std_msgs/msg/Header"]
    if "seq" in H.__dataclass_fields__:  # ROS 1
        return H(seq=0, stamp=stamp(ts, t), frame_id=frame)
    return H(stamp=stamp(ts, t), frame_id=frame)


def vector(ts, x=0.0, y=0.0, z=0.0):
    return ts.types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)


def twist(ts, v=V, w=W):
    return ts.types["geometry_msgs/msg/Twist"](linear=vector(ts, v), angular=vector(ts, z=w))


def tf_message(ts, t: float, frames: list[tuple[str, str, tuple[float, float, float]]]):
    T = ts.types
    transforms = [
        T["geometry_msgs/msg/TransformStamped"](
            header=header(ts, t, parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=vector(ts, *xyz),
                rotation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )
        for parent, child, xyz in frames
    ]
    return T["tf2_msgs/msg/TFMessage"](transforms=transforms)


def apriltag_array(ts, t: float, detections: list[tuple[list[int], tuple[float, float, float]]]):
    T = ts.types
    items = []
    for ids, xyz in detections:
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=xyz[0], y=xyz[1], z=xyz[2]),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        )
        pwc = T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36))
        stamped = T["geometry_msgs/msg/PoseWithCovarianceStamped"](
            header=header(ts, t, "camera"), pose=pwc
        )
        items.append(
            T["apriltag_ros/msg/AprilTagDetection"](
                id=np.array(ids, dtype=np.int32), size=np.full(len(ids), 0.1), pose=stamped
            )
        )
    return T["apriltag_ros/msg/AprilTagDetectionArray"](
        header=header(ts, t, "camera"), detections=items
    )


CONTROL_TIMES = np.round(np.arange(0.0, 6.0, 0.1), 3) + 100.0
CAMERA_TIMES = np.round(np.arange(0.05, 6.0, 0.5), 3) + 100.0


def visible(t: float) -> list[int]:
    """Tags in front of the camera (what a detector would report)."""
    pose = true_pose(t - 100.0)
    return [i for i, xy in TAGS.items() if camera_point(pose, xy)[2] > 0.2]


def write_ros1(path: Path) -> Path:
    ts = get_typestore(Stores.ROS1_NOETIC)
    for name, text in APRILTAG_ROS.items():
        ts.register(get_types_from_msg(text, name))
    with Writer1(path) as w:
        cmd = w.add_connection("/cmd_vel", "geometry_msgs/msg/Twist", typestore=ts)
        det = w.add_connection(
            "/tag_detections", "apriltag_ros/msg/AprilTagDetectionArray", typestore=ts
        )
        for t in CONTROL_TIMES:
            msg = twist(ts)
            w.write(cmd, round(t * 1e9), ts.serialize_ros1(msg, msg.__msgtype__))
        for t in CAMERA_TIMES:
            pose = true_pose(t - 100.0)
            items = [([i], camera_point(pose, TAGS[i])) for i in visible(t)]
            items.append(([1, 2], (0.0, 0.0, 1.0)))  # a bundle: skipped and counted
            msg = apriltag_array(ts, t, items)
            # the camera's stamp is older than the time the bag got it
            w.write(det, round((t + 0.03) * 1e9), ts.serialize_ros1(msg, msg.__msgtype__))
    return path


def write_ros2(path: Path, wheels: MecanumGeometry | None = None, axes: str = "optical") -> Path:
    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    with Writer2(path, version=9) as w:
        if wheels is None:
            motion = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts)
        else:
            motion = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=ts)
        tf = w.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=ts)
        for t in CONTROL_TIMES:
            if wheels is None:
                cov = T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=twist(ts), covariance=np.zeros(36)
                )
                pose = T["geometry_msgs/msg/PoseWithCovariance"](
                    pose=T["geometry_msgs/msg/Pose"](
                        position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                    ),
                    covariance=np.zeros(36),
                )
                msg = T["nav_msgs/msg/Odometry"](
                    header=header(ts, t, "odom"), child_frame_id="base_link", pose=pose, twist=cov
                )
            else:
                speeds = twist_to_wheels(np.array([[V, 0.0, W]]), wheels)[0]
                # joints in a scrambled order, plus one that is not a wheel
                msg = T["sensor_msgs/msg/JointState"](
                    header=header(ts, t, ""),
                    name=["rr", "camera_pan", "fl", "rl", "fr"],
                    position=np.zeros(5),
                    velocity=np.array([speeds[3], 9.0, speeds[0], speeds[2], speeds[1]]),
                    effort=np.zeros(5),
                )
            w.write(motion, round((t + 0.01) * 1e9), ts.serialize_cdr(msg, msg.__msgtype__))
        for t in CAMERA_TIMES:
            pose = true_pose(t - 100.0)
            frames = [("camera", f"tag_{i}", camera_point(pose, TAGS[i], axes)) for i in visible(t)]
            frames.append(("odom", "base_link", (1.0, 2.0, 0.0)))  # not a tag
            frames.append(("elsewhere", "tag_3", (1.0, 0.0, 0.0)))  # a tag, wrong camera
            msg = tf_message(ts, t, frames)
            w.write(tf, round((t + 0.02) * 1e9), ts.serialize_cdr(msg, msg.__msgtype__))
    return path


def expected_detections() -> tuple[list[float], list[int], list[tuple[float, float]]]:
    times, ids, z = [], [], []
    for t in CAMERA_TIMES:
        for i in visible(t):
            times.append(float(t))
            ids.append(i)
            z.append(true_measurement(true_pose(t - 100.0), TAGS[i]))
    return times, ids, z


def check_detections(run) -> None:
    times, ids, z = expected_detections()
    d = run.detections
    assert d.tag_id.tolist() == ids
    np.testing.assert_allclose(d.t, times, atol=1e-9, rtol=0)  # header stamps, not bag times
    np.testing.assert_allclose(d.range, [r for r, _ in z], atol=1e-9)
    np.testing.assert_allclose(d.bearing, [b for _, b in z], atol=1e-9)


def test_ros1_twist_and_apriltag_ros_detections(tmp_path: Path) -> None:
    bag = write_ros1(tmp_path / "run.bag")
    spec = RosbagSpec(
        detections_topic="/tag_detections",
        twist_topic="/cmd_vel",
        camera_mounting=MOUNT,
        camera_pitch=PITCH,
    )
    run, report = read_rosbag(bag, spec)
    assert run.controls.kind == "twist"
    np.testing.assert_allclose(run.controls.t, CONTROL_TIMES, atol=1e-9, rtol=0)  # bag times
    assert run.controls.values.tolist() == [[V, 0.0, W]] * len(CONTROL_TIMES)
    check_detections(run)
    assert report.bundles_skipped == len(CAMERA_TIMES)
    assert report.bag_stamps_used == len(CONTROL_TIMES)  # Twist has no header
    assert report.detections_kept == len(run.detections.t) > 10


@pytest.mark.parametrize("axes", ["optical", "body"])
def test_ros2_odometry_and_tf_frames(tmp_path: Path, axes: str) -> None:
    bag = write_ros2(tmp_path / "bag2", axes=axes)
    spec = RosbagSpec(
        detections_topic="/tf",
        twist_topic="/odom",
        camera_mounting=MOUNT,
        camera_pitch=PITCH,
        camera_axes=axes,
        camera_frame="camera",
    )
    run, report = read_rosbag(bag, spec)
    np.testing.assert_allclose(run.controls.t, CONTROL_TIMES, atol=1e-9, rtol=0)  # headers
    np.testing.assert_allclose(run.controls.values, [[V, 0.0, W]] * len(CONTROL_TIMES))
    check_detections(run)
    assert report.frames_skipped == 2 * len(CAMERA_TIMES)
    assert report.bag_stamps_used == 0


def test_ros2_wheel_speeds_by_joint_name(tmp_path: Path) -> None:
    robot = MecanumGeometry()
    bag = write_ros2(tmp_path / "wheels", wheels=robot)
    spec = RosbagSpec(
        detections_topic="/tf",
        wheels_topic="/joint_states",
        wheel_joints=("fl", "fr", "rl", "rr"),
        robot=robot,
        camera_mounting=MOUNT,
        camera_pitch=PITCH,
        camera_frame="camera",
    )
    run, _ = read_rosbag(bag, spec)
    assert run.controls.kind == "wheels"
    np.testing.assert_allclose(run.control_twist(), [[V, 0.0, W]] * len(CONTROL_TIMES), atol=1e-12)


def test_missing_topic_lists_the_bag_topics(tmp_path: Path) -> None:
    bag = write_ros1(tmp_path / "run.bag")
    with pytest.raises(InputError) as err:
        read_rosbag(bag, RosbagSpec(detections_topic="/tf", twist_topic="/cmd_vel"))
    assert "topic /tf not in the bag" in str(err.value)
    assert "/tag_detections (apriltag_ros/msg/AprilTagDetectionArray)" in str(err.value)


def test_wrong_message_type_is_named(tmp_path: Path) -> None:
    bag = write_ros1(tmp_path / "run.bag")
    with pytest.raises(InputError, match="tag poses must come as"):
        read_rosbag(bag, RosbagSpec(detections_topic="/cmd_vel", twist_topic="/cmd_vel"))
    with pytest.raises(InputError, match="a twist topic must be one of"):
        read_rosbag(
            bag, RosbagSpec(detections_topic="/tag_detections", twist_topic="/tag_detections")
        )


def test_missing_bag(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="bag not found"):
        read_rosbag(tmp_path / "nope.bag", RosbagSpec(detections_topic="/tf", twist_topic="/x"))


def test_spec_needs_one_motion_topic() -> None:
    with pytest.raises(ValueError, match="exactly one"):
        RosbagSpec(detections_topic="/tf")
    with pytest.raises(ValueError, match="wheel_joints"):
        RosbagSpec(detections_topic="/tf", wheels_topic="/joint_states")


def test_command_line_converts_and_the_run_replays(tmp_path: Path) -> None:
    bag = write_ros2(tmp_path / "bag2")
    out = tmp_path / "run"
    argv = ["convert", "rosbag", str(bag), "--out", str(out), "--twist-topic", "/odom"]
    argv += ["--detections-topic", "/tf", "--camera-frame", "camera", "--camera-pitch", str(PITCH)]
    argv += ["--camera-mounting", *map(str, MOUNT), "--name", "circle"]
    assert main(argv) == 0
    run = read_run(out)
    assert run.meta.name == "circle"
    np.testing.assert_allclose(run.meta.camera_mounting, MOUNT)
    check_detections(run)
    # exact twist and sightings: the map is off only by eq. (6)'s Euler steps on the arc (cm)
    result = replay(run)
    assert sorted(result.landmarks) == sorted(set(expected_detections()[1]))
    for i, xy in result.landmarks.items():
        assert np.linalg.norm(xy - TAGS[i]) < 0.05
    assert main(argv) == 2  # the folder exists now: refused, one line, exit 2


@pytest.mark.parametrize(
    ("pattern", "problem"),
    [
        (r"tag_\d+", "needs a group 1"),
        (r"(tag)_\d+", "needs a group 1"),
        (r"tag_(\d*)", "needs a group 1"),  # may match nothing: int("") fails
        (r"tag_(\d+", "is not a regular expression"),
    ],
)
def test_a_tag_frame_pattern_without_a_numeric_group_1_is_refused_up_front(
    pattern: str, problem: str
) -> None:
    with pytest.raises(ValueError, match=problem):
        RosbagSpec(detections_topic="/tf", twist_topic="/odom", tag_frame_pattern=pattern)


@pytest.mark.parametrize("good", [r"tag_(\d+)$", r"(?:tag|marker)_([0-9]+)", r"t(?:ag)?(\d)"])
def test_tag_frame_patterns_with_a_numeric_group_1_are_accepted(good: str) -> None:
    assert RosbagSpec(detections_topic="/tf", twist_topic="/o", tag_frame_pattern=good)


@pytest.mark.parametrize(
    ("extra", "word"),
    [
        (["--start", "nan", "0", "0"], "--start"),
        (["--start", "1e308", "0", "0"], "--start"),
        (["--camera-mounting", "0", "inf", "0"], "--camera-mounting"),
        (["--tag-frame-pattern", r"(tag)_\d+"], "group 1"),
    ],
)
def test_bad_options_name_the_bag_and_the_option_not_run_json(
    tmp_path: Path, capsys, extra: list[str], word: str
) -> None:
    bag = write_ros2(tmp_path / "bag2")
    argv = ["convert", "rosbag", str(bag), "--out", str(tmp_path / "run"), "--twist-topic"]
    argv += ["/odom", "--detections-topic", "/tf", *extra]
    assert main(argv) == 2
    err = capsys.readouterr().err
    # a value that is wrong on its own is refused by the parser, naming the option; one that
    # only the bag's spec can judge is refused naming the bag
    parser_says = err.startswith("python -m ekfslam convert rosbag: error: argument ")
    assert err.count("\n") == 1 and (parser_says or err.startswith(f"error: {bag}: "))
    assert word in err
    assert "run.json" not in err and not (tmp_path / "run").exists()


def test_a_plain_folder_is_not_a_bag(tmp_path: Path) -> None:
    (tmp_path / "photos").mkdir()
    with pytest.raises(InputError, match=r"no metadata\.yaml") as caught:
        read_rosbag(tmp_path / "photos", RosbagSpec(detections_topic="/tf", twist_topic="/x"))
    assert caught.value.path == str(tmp_path / "photos")


def test_a_file_that_is_not_a_bag_is_one_error(tmp_path: Path) -> None:
    (tmp_path / "notes.bag").write_text("not a bag\n")
    with pytest.raises(InputError, match="cannot read the bag"):
        read_rosbag(tmp_path / "notes.bag", RosbagSpec(detections_topic="/tf", twist_topic="/x"))
