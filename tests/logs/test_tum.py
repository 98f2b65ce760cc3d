"""TUM export: the quaternion convention, exact round trips, and the files `export_tum` writes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ekfslam.cli.main import main
from ekfslam.errors import InputError
from ekfslam.logs.runlog import Controls, Detections, GroundTruth, RunLog, RunMeta, write_run
from ekfslam.logs.tum import (
    GROUNDTRUTH,
    MAP,
    MAP_TRUTH,
    TRAJECTORY,
    export_tum,
    landmarks_to_tum,
    last_pose_per_time,
    poses_to_tum,
    read_tum,
    write_tum,
)
from ekfslam.pipeline import replay


def quaternion_matrix(qx: float, qy: float, qz: float, qw: float) -> np.ndarray:
    """The textbook rotation matrix of a unit quaternion (Hamilton, scalar last)."""
    return np.array(
        [
            [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
            [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
            [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)],
        ]
    )


@pytest.mark.parametrize("theta", [0.0, 0.3, math.pi / 2, -2.5, math.pi - 1e-9, -math.pi])
def test_quaternion_rotates_the_body_x_axis_to_the_heading(theta: float) -> None:
    row = poses_to_tum([7.0], [[1.0, -2.0, theta]])[0]
    assert row[:4].tolist() == [7.0, 1.0, -2.0, 0.0]
    R = quaternion_matrix(*row[4:])
    np.testing.assert_allclose(
        R @ [1.0, 0.0, 0.0], [math.cos(theta), math.sin(theta), 0.0], atol=1e-12
    )
    np.testing.assert_allclose(R @ [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], atol=1e-12)


def test_write_then_read_gives_the_same_times_and_poses(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    t = 1248446188.323 + np.cumsum(rng.uniform(0.001, 0.5, 50))  # Unix times, as MRCLAM's
    poses = np.column_stack([rng.normal(size=(50, 2)), rng.uniform(-math.pi, math.pi, 50)])
    path = write_tum(tmp_path / "a.tum", poses_to_tum(t, poses))
    t2, poses2 = read_tum(path)
    assert t2.tolist() == t.tolist()  # bit for bit: times are printed with repr
    assert poses2[:, :2].tolist() == poses[:, :2].tolist()
    dtheta = (poses2[:, 2] - poses[:, 2] + math.pi) % (2 * math.pi) - math.pi
    assert np.abs(dtheta).max() < 1e-12
    first = path.read_text().splitlines()[0].split()
    assert len(first) == 8 and first[3] == "0.0"


def test_last_pose_per_time_keeps_the_update_after_the_prediction() -> None:
    t = [0.0, 1.0, 1.0, 2.0, 2.0, 2.0]
    poses = np.arange(18, dtype=float).reshape(6, 3)
    t2, p2 = last_pose_per_time(t, poses)
    assert t2.tolist() == [0.0, 1.0, 2.0]
    assert p2[:, 0].tolist() == [0.0, 6.0, 15.0]


def test_landmarks_have_their_id_as_time_sorted() -> None:
    rows = landmarks_to_tum({12: [1.0, 2.0], 3: np.array([-0.5, 0.25])})
    assert rows[:, 0].tolist() == [3.0, 12.0]
    assert rows[:, 1:3].tolist() == [[-0.5, 0.25], [1.0, 2.0]]
    assert rows[:, 3:].tolist() == [[0.0, 0.0, 0.0, 0.0, 1.0]] * 2


@pytest.mark.parametrize(
    ("text", "line", "problem"),
    [
        ("# t x y z qx qy qz qw\n1 2 3 0 0 0 0 1\n1 2 3\n", 3, "expected 8 numbers"),
        ("1 2 3 0 0 0 0 1\n\n2 2 3 0 0 0 zero 1\n", 3, "not a number"),
        ("1 2 3 0 0.7071 0 0 0.7071\n", 1, "not a planar pose"),
        ("1 2 3 0.5 0 0 0 1\n", 1, "not a planar pose"),
        ("1 2 3 0 0 0 0 0\n", 1, "quaternion is zero"),
        ("1 2 nan 0 0 0 0 1\n", 1, "finite"),
    ],
)
def test_malformed_tum_names_the_line(tmp_path: Path, text: str, line: int, problem: str) -> None:
    path = tmp_path / "bad.tum"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_tum(path)
    assert err.value.line == line
    assert problem in str(err.value)


def small_run() -> RunLog:
    """A robot driving a circle of radius 1 m past three tags, with exact measurements."""
    v, w = 0.5, 0.5
    t = np.arange(0.0, 8.0, 0.1)
    radius = v / w  # a unicycle at constant (v, w) from the origin, heading 0
    heading = (w * t + math.pi) % (2 * math.pi) - math.pi
    truth = np.column_stack([radius * np.sin(w * t), radius * (1 - np.cos(w * t)), heading])
    tags = {1: np.array([2.0, 0.5]), 2: np.array([0.0, 2.5]), 3: np.array([-1.5, 1.0])}
    det_t, det_id, rng_, brg = [], [], [], []
    for k in range(0, len(t), 3):
        x, y, th = truth[k]
        for i, (mx, my) in tags.items():
            det_t.append(t[k])
            det_id.append(i)
            rng_.append(math.hypot(mx - x, my - y))
            brg.append((math.atan2(my - y, mx - x) - th + math.pi) % (2 * math.pi) - math.pi)
    return RunLog(
        meta=RunMeta(name="circle", source="recorded", nominal_start=np.zeros(3), tag_map=tags),
        controls=Controls(t=t, kind="twist", values=np.tile([v, 0.0, w], (len(t), 1))),
        detections=Detections(
            t=np.array(det_t), tag_id=np.array(det_id), range=np.array(rng_), bearing=np.array(brg)
        ),
        groundtruth=GroundTruth(t=t, pose=truth),
    )


def test_export_writes_trajectory_map_and_truth(tmp_path: Path) -> None:
    run = small_run()
    result = replay(run)
    written = export_tum(run, result, tmp_path / "out")
    assert sorted(written) == sorted([TRAJECTORY, MAP, GROUNDTRUTH, MAP_TRUTH])
    t, poses = read_tum(written[TRAJECTORY])
    assert np.all(np.diff(t) > 0)
    assert t[-1] == result.history.t[-1]
    np.testing.assert_allclose(poses[-1, :2], result.mu[:2], atol=1e-12)
    ids, lm = read_tum(written[MAP])
    assert ids.tolist() == [1.0, 2.0, 3.0]
    np.testing.assert_allclose(lm[:, :2], [result.landmarks[i] for i in (1, 2, 3)], atol=1e-12)
    ids, truth = read_tum(written[MAP_TRUTH])
    assert truth[:, :2].tolist() == [run.meta.tag_map[i].tolist() for i in (1, 2, 3)]
    gt_t, gt = read_tum(written[GROUNDTRUTH])
    assert gt_t.tolist() == run.groundtruth.t.tolist()
    np.testing.assert_allclose(gt[:, :2], run.groundtruth.pose[:, :2], atol=0)
    # exact measurements of a circle: the estimate should follow the truth to a few cm
    assert np.abs(lm[:, :2] - truth[:, :2]).max() < 0.05


def test_no_truth_no_truth_files(tmp_path: Path) -> None:
    run = small_run()
    bare = RunLog(
        meta=RunMeta(name="bare", source="recorded", nominal_start=np.zeros(3)),
        controls=run.controls,
        detections=run.detections,
    )
    written = export_tum(bare, replay(bare), tmp_path)
    assert sorted(written) == sorted([TRAJECTORY, MAP])
    assert not (tmp_path / GROUNDTRUTH).exists()


def test_command_line_writes_the_files(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    folder = write_run(small_run(), tmp_path / "run")
    assert main(["tum", str(folder), "--out", str(tmp_path / "tum")]) == 0
    printed = capsys.readouterr().out.split()
    assert sorted(Path(p).name for p in printed) == sorted(
        [TRAJECTORY, MAP, GROUNDTRUTH, MAP_TRUTH]
    )
    assert len(read_tum(tmp_path / "tum" / MAP)[0]) == 3
