"""``python -m ekfslam convert mrclam|rosbag ...``: a recorded log -> our run folder.

One sub-command per input format, each with only its own options.
"""

from __future__ import annotations

import argparse
import math
import re

from ekfslam.cli import args as ca
from ekfslam.cli.common import mrclam_folder
from ekfslam.core.kinematics import MecanumGeometry
from ekfslam.errors import InputError
from ekfslam.logs import rosbag
from ekfslam.logs.mrclam.calibration import MRCLAM_CALIBRATION, calibrate_commands
from ekfslam.logs.mrclam.load import load_mrclam
from ekfslam.logs.rosbag import read_rosbag
from ekfslam.logs.rosbag_spec import RosbagSpec
from ekfslam.logs.runlog import validate_run, write_run


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``convert`` and its formats (`help` is the line of `ekfslam.cli.main.COMMANDS`)."""
    parser = subparsers.add_parser(name, help=help)
    formats = parser.add_subparsers(dest="format", required=True)
    _add_mrclam(formats)
    _add_rosbag(formats)


def _add_mrclam(formats: argparse._SubParsersAction) -> None:
    p = formats.add_parser(
        "mrclam",
        help="one robot of a MRCLAM dataset -> a run folder (with its Vicon truth if it has one)",
    )
    p.add_argument(
        "dataset", type=ca.mrclam_dataset, help="a MRCLAM dataset: its folder or its number 1-9"
    )
    p.add_argument(
        "--robot",
        type=ca.one_of(ca.ROBOTS, "MRCLAM robots"),
        required=True,
        help="which robot (1-5)",
    )
    ca.add_run_folder_arguments(p)
    ca.add_max_range_argument(p)
    p.add_argument(
        "--calibrate",
        action="store_true",
        help="shift and scale the commands by MRCLAM_CALIBRATION (lag 0.25 s, v x0.90, w x0.935)",
    )
    p.set_defaults(func=cmd_convert_mrclam)


def cmd_convert_mrclam(args: argparse.Namespace) -> int:
    folder = mrclam_folder(args.dataset)
    run, report = load_mrclam(folder, args.robot, max_range=args.max_range)
    if args.calibrate:
        run = calibrate_commands(run, MRCLAM_CALIBRATION)
    try:  # load_mrclam checks what it reads; name the dataset, not a file the user never gave
        validate_run(run)
    except InputError as err:
        raise InputError(folder, None, f"robot {args.robot}: {err.problem}") from None
    write_run(run, args.out, overwrite=args.overwrite)
    print(report.summary())
    print(f"wrote {args.out}")
    return 0


def _add_rosbag(formats: argparse._SubParsersAction) -> None:
    p = formats.add_parser(
        "rosbag",
        help="a ROS 1 .bag or ROS 2 bag folder -> a run folder",
        description=rosbag.__doc__.split("\n\n")[0],
    )
    p.add_argument(
        "bag", type=ca.given_path, nargs="+", help="ROS 2 bag folder, or ROS 1 .bag file(s)"
    )
    ca.add_run_folder_arguments(p)
    p.add_argument(
        "--detections-topic",
        required=True,
        type=ca.non_empty,
        help="TFMessage or AprilTag detections",
    )
    motion = p.add_mutually_exclusive_group(required=True)
    motion.add_argument("--twist-topic", type=ca.non_empty, help="Twist, TwistStamped or Odometry")
    motion.add_argument(
        "--wheels-topic", type=ca.non_empty, help="JointState with four wheel speeds (rad/s)"
    )
    p.add_argument("--wheel-joints", nargs=4, type=ca.non_empty, metavar=("FL", "FR", "RL", "RR"))
    p.add_argument(
        "--wheel-geometry",
        nargs=3,
        type=ca.positive(1.0, why="m"),
        metavar=("RADIUS", "LX", "LY"),
        help="mecanum wheel radius, lx, ly in m, each in (0, 1] (with --wheels-topic)",
    )
    p.add_argument(
        "--camera-mounting",
        nargs=3,
        type=ca.finite(),
        default=(0.0, 0.0, 0.0),
        metavar=("X", "Y", "YAW"),
        help="camera on the robot, m, m, rad (within ±1 m, ±π)",
    )
    p.add_argument(
        "--camera-pitch",
        type=ca.real(-math.pi / 2, math.pi / 2),
        default=0.0,
        help="rad, positive looks down, within ±π/2",
    )
    p.add_argument("--camera-axes", choices=["optical", "body"], default="optical")
    p.add_argument(
        "--camera-frame", type=ca.non_empty, help="keep only TF transforms from this parent frame"
    )
    p.add_argument(
        "--tag-frame-pattern",
        type=ca.regex,
        default=RosbagSpec.tag_frame_pattern,
        help="regex on TF child frames; group 1 is the tag id",
    )
    p.add_argument(
        "--start",
        nargs=3,
        type=ca.finite(),
        default=(0.0, 0.0, 0.0),
        metavar=("X", "Y", "THETA"),
        help="nominal start pose, m, m, rad (within ±1000 m, ±π)",
    )
    p.add_argument("--name", type=ca.non_empty, help="the run's name (default: the bag's name)")
    p.add_check(ca.triple_check("--camera-mounting", (1.0, 1.0, math.pi), ("X", "Y", "YAW")))
    p.add_check(ca.triple_check("--start", (1000.0, 1000.0, math.pi), ("X", "Y", "THETA")))
    p.set_defaults(func=cmd_convert_rosbag)


def cmd_convert_rosbag(args: argparse.Namespace) -> int:
    robot = None if args.wheel_geometry is None else MecanumGeometry(*args.wheel_geometry)
    try:
        spec = RosbagSpec(
            detections_topic=args.detections_topic,
            twist_topic=args.twist_topic,
            wheels_topic=args.wheels_topic,
            wheel_joints=None if args.wheel_joints is None else tuple(args.wheel_joints),
            robot=robot,
            camera_mounting=tuple(args.camera_mounting),
            camera_pitch=args.camera_pitch,
            camera_axes=args.camera_axes,
            tag_frame_pattern=args.tag_frame_pattern,
            camera_frame=args.camera_frame,
            name=args.name or args.bag[0].stem,
            nominal_start=tuple(args.start),
        )
    except (ValueError, re.error) as exc:
        raise InputError(args.bag[0], None, str(exc)) from None
    run, report = read_rosbag(args.bag, spec)
    write_run(run, args.out, overwrite=args.overwrite)
    span = run.controls.t[-1] - run.controls.t[0]
    print(
        f"wrote {args.out}: {report.motion_messages} controls, {report.detections_kept} detections "
        f"over {span:.1f} s ({report.frames_skipped} TF frames, {report.bundles_skipped} bundles, "
        f"{report.at_camera_skipped} sightings at the camera skipped)"
    )
    return 0
