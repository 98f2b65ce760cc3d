"""Tests of the seed's arena and of the simulated robot (ekfslam.core.arena,
ekfslam.sim.simulation).

The checks recompute what a detection should be from ground truth with independent code, so the
simulator cannot agree with itself by construction.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ekfslam.core.arena import SEED_ARENA, Arena, Tag
from ekfslam.core.camera import Camera, pinhole_camera
from ekfslam.sim.scenarios import realistic
from ekfslam.sim.simulation import (
    SimulationConfig,
    arc_increment,
    config_from_dict,
    plan_commands,
    simulate,
    visible,
    waypoints,
)

NOISELESS = dict(
    wheel_noise_sigma=0.0,
    wheel_noise_fraction=0.0,
    start_error=(0.0, 0.0, 0.0),
    range_noise_sigma=0.0,
    bearing_noise_sigma=0.0,
    dropout=0.0,
)


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def pose_at(log, t):
    """Ground-truth poses (M, 3) linearly interpolated at times t (M,)."""
    gt = log.groundtruth
    theta = np.unwrap(gt.pose[:, 2])
    return np.column_stack(
        [np.interp(t, gt.t, gt.pose[:, i]) for i in (0, 1)] + [np.interp(t, gt.t, theta)]
    )


def residuals(log, arena=SEED_ARENA):
    """Measured minus true (range, bearing) of every detection, from interpolated ground truth."""
    d = log.detections
    pose = pose_at(log, d.t)
    tags = arena.tag_map()
    tag_xy = np.array([tags[int(i)] for i in d.tag_id])
    dx, dy = tag_xy[:, 0] - pose[:, 0], tag_xy[:, 1] - pose[:, 1]
    r_true = np.sqrt(dx**2 + dy**2)
    b_true = np.arctan2(dy, dx) - pose[:, 2]
    return d.range - r_true, wrap(d.bearing - b_true), r_true


def expected_visible(pose, tag: Tag, r_min=0.1, r_max=2.0, incidence_deg=75.0):
    """(visible, distance to the nearest decision boundary) for one tag, written out by hand.

    The default camera: 640x480, fx = fy = 320 / tan(32.5°), centred, k1 = -0.08, k2 = 0.03,
    12 cm above the floor, level, 6 cm ahead of the robot's centre. The tag's printed outline
    (a 0.2 m square: the 0.16 m black square and its white module) centred 0.15 m above the
    floor must project at least 1 px inside the image, sampled along its edges.
    """
    x, y, th = pose
    cam_x, cam_y, cam_z = x + 0.06 * math.cos(th), y + 0.06 * math.sin(th), 0.12
    f = 320.0 / math.tan(math.radians(32.5))
    nx, ny = tag.normal
    px_margin = math.inf
    for s in np.linspace(-1.0, 1.0, 17):
        for a, b in ((s, 1.0), (s, -1.0), (1.0, s), (-1.0, s)):  # (along the wall, up) / 0.1 m
            wx, wy = tag.position[0] - ny * 0.1 * a, tag.position[1] + nx * 0.1 * a
            dx, dy, dz = wx - cam_x, wy - cam_y, 0.15 + 0.1 * b - cam_z
            ahead = dx * math.cos(th) + dy * math.sin(th)
            left = -dx * math.sin(th) + dy * math.cos(th)
            if ahead <= 0.01:
                px_margin = -math.inf
                continue
            u, v = -left / ahead, -dz / ahead  # right and down, on the unit plane
            r2 = u * u + v * v
            k = 1.0 - 0.08 * r2 + 0.03 * r2 * r2
            col, row = f * u * k + 319.5, f * v * k + 239.5
            px_margin = min(px_margin, col + 0.5 - 1.0, 639.5 - 1.0 - col)
            px_margin = min(px_margin, row + 0.5 - 1.0, 479.5 - 1.0 - row)
    r = math.hypot(tag.position[0] - x, tag.position[1] - y)
    sx, sy, sz = cam_x - tag.position[0], cam_y - tag.position[1], cam_z - 0.15
    cos_inc = (sx * nx + sy * ny) / math.sqrt(sx * sx + sy * sy + sz * sz)
    incidence = math.degrees(math.acos(max(-1.0, min(1.0, cos_inc))))
    ok = r_min <= r <= r_max and px_margin >= 0 and incidence <= incidence_deg
    margin = min(abs(r - r_min), abs(r - r_max), abs(px_margin) / 500.0)
    return ok, min(margin, abs(incidence - incidence_deg) / 57.3)


@pytest.fixture(scope="module")
def square():
    return simulate(SimulationConfig(trajectory="square", seed=1))


@pytest.fixture(scope="module")
def octagon():
    return simulate(SimulationConfig(trajectory="octagon", seed=1))


@pytest.fixture(scope="module")
def noiseless():
    return simulate(SimulationConfig(trajectory="octagon", seed=3, **NOISELESS))


# --- the arena ---------------------------------------------------------------------------------


def test_seed_arena_matches_section_1():
    assert SEED_ARENA.half_size == 0.75
    expected = [(0.75, 0.375), (0.75, -0.375), (0.375, -0.75), (0.375, 0.75)]
    expected += [(-0.375, 0.75), (-0.75, 0.375), (-0.75, -0.375), (-0.375, -0.75)]
    assert np.array_equal(SEED_ARENA.tag_positions(), np.array(expected))
    assert sorted(SEED_ARENA.tag_map()) == list(range(8))
    assert np.array_equal(SEED_ARENA.nominal_start, [-0.375, -0.375, 0.0])
    for tag in SEED_ARENA.tags:
        assert np.isclose(np.linalg.norm(tag.normal), 1.0)
        assert np.dot(tag.normal, -tag.position) > 0  # faces the centre
        assert np.max(np.abs(tag.position)) == 0.75  # on a wall
    assert np.array_equal(SEED_ARENA.tags[0].normal, [-1.0, 0.0])


def test_contains():
    assert SEED_ARENA.contains([0.7, -0.7])
    assert not SEED_ARENA.contains([0.7, -0.7], margin=0.1)
    assert not SEED_ARENA.contains([0.0, 0.76])
    assert SEED_ARENA.contains(np.array([[0.0, 0.0, 3.0], [0.8, 0.0, 0.0]])).tolist() == [
        True,
        False,
    ]


# --- paths and the controller -----------------------------------------------------------------


def test_square_waypoints_pass_through_the_nominal_start():
    wp = waypoints("square", 0.75, 2)
    assert wp.shape == (9, 2)
    assert np.allclose(wp[0], [-0.375, -0.375]) and np.allclose(wp[-1], wp[0])
    assert np.allclose(np.abs(wp), 0.375)
    # counter-clockwise: positive signed area
    x, y = wp[:5, 0], wp[:5, 1]
    assert 0.5 * np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]) == pytest.approx(0.75**2)


def test_octagon_is_regular_starts_at_the_nominal_start_and_keeps_off_the_walls():
    wp = waypoints("octagon", 0.75, 2)
    assert wp.shape == (17, 2)
    assert np.allclose(wp[0], [-0.375, -0.375])
    sides = np.linalg.norm(np.diff(wp, axis=0), axis=1)
    assert np.allclose(sides, 2 * 0.75 / math.sqrt(2) * math.sin(math.pi / 8))
    assert np.allclose(np.linalg.norm(wp, axis=1), 0.75 / math.sqrt(2))
    assert 0.75 - np.abs(wp).max() >= 0.15
    x, y = wp[:9, 0], wp[:9, 1]
    assert 0.5 * np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]) > 0


@pytest.mark.parametrize("trajectory", ["square", "octagon"])
def test_commanded_path_closes_after_each_lap(trajectory):
    config = SimulationConfig(trajectory=trajectory, laps=3)
    plan = plan_commands(config, SEED_ARENA.nominal_start)
    reached = plan.believed[plan.waypoint_index]
    assert np.abs(reached[:, :2] - plan.waypoints).max() < 1e-3
    n = 4 if trajectory == "square" else 8
    for lap in range(1, 4):
        assert np.linalg.norm(reached[lap * n, :2] - [-0.375, -0.375]) < 1e-3
    # the robot drives forward only, within its limits
    twist = plan.wheels @ config.robot.wheels_to_twist_matrix.T
    assert twist[:, 0].min() >= -1e-12 and twist[:, 0].max() <= 0.15 + 1e-12
    assert np.abs(twist[:, 1]).max() < 1e-12 and np.abs(twist[:, 2]).max() <= 0.8 + 1e-12


def test_arc_increment_matches_fine_euler_steps():
    twist, dt, theta = np.array([0.12, -0.03, 0.7]), 0.4, 2.5
    n = 20000
    pose = np.array([0.0, 0.0, theta])
    for _ in range(n):  # eq. (6) with tiny steps
        c, s = math.cos(pose[2]), math.sin(pose[2])
        h = dt / n
        pose += [h * (twist[0] * c - twist[1] * s), h * (twist[0] * s + twist[1] * c), h * twist[2]]
    assert np.allclose(arc_increment(theta, twist, dt), pose - [0, 0, theta], atol=1e-6)


# --- the run log ------------------------------------------------------------------------------


def test_default_runs_have_realistic_size(square, octagon):
    for log, low, high in ((square, 40.0, 60.0), (octagon, 45.0, 75.0)):
        duration = log.controls.t[-1]
        assert low <= duration <= high
        assert len(log.detections.t) > 300
        counts = np.bincount(log.detections.tag_id, minlength=8)
        assert counts.min() >= 2, counts  # every tag seen more than once


def test_log_layout(square):
    log, config = square, SimulationConfig(seed=1)
    c, d, gt = log.controls, log.detections, log.groundtruth
    n = len(c.t)
    assert c.kind == "wheels" and c.values.shape == (n, 4)
    assert np.array_equal(c.t, np.arange(n) / 20.0)
    assert np.all(c.values[-1] == 0.0)
    assert np.array_equal(gt.t, c.t) and gt.pose.shape == (n, 3)
    k = np.rint(d.t * 10.0)
    assert np.array_equal(d.t, k / 10.0) and d.t.max() <= c.t[-1]
    order = np.lexsort((d.tag_id, d.t))
    assert np.array_equal(order, np.arange(len(d.t)))
    assert len({(t, i) for t, i in zip(d.t, d.tag_id, strict=True)}) == len(d.t)
    for angles in (d.bearing, gt.pose[:, 2]):
        assert angles.min() >= -np.pi and angles.max() < np.pi
    meta = log.meta
    # seed 1 without the seed's start error is not the shipped square-2laps: its name says so
    assert meta.source == "simulated" and meta.name == "square-2laps-seed1"
    assert meta.control_rate_hz == 20.0 and meta.camera_rate_hz == 10.0
    assert meta.robot == config.robot and np.array_equal(meta.camera_mounting, [0.06, 0, 0])
    assert np.array_equal(meta.nominal_start, SEED_ARENA.nominal_start)
    assert set(meta.tag_map) == set(range(8))
    sim = json.loads(json.dumps(meta.simulation))  # JSON-serialisable, unchanged by a round trip
    assert sim == meta.simulation
    assert sim["seed"] == 1 and sim["laps"] == 2 and sim["trajectory"] == "square"
    assert sim["noise"]["range_noise_sigma"] == 0.02 and sim["outliers"] == {
        "wrong_id": 0,
        "range": 0,
    }
    assert config_from_dict(sim["config"]) == config


def test_config_round_trip_and_validation():
    config = SimulationConfig(trajectory="octagon", laps=3, start_error=(0.01, -0.02, 0.1))
    assert config_from_dict(json.loads(json.dumps(config.to_dict()))) == config
    camera = Camera(
        800,
        600,
        610.5,
        611.25,
        401.0,
        297.5,
        (-0.1, 0.02, 0.001, -0.002),
        mount_height=0.2,
        pitch=0.05,
    )
    other = SimulationConfig(camera=camera, camera_mounting=[0.05, -0.01, 0.1], tag_size=0.1)
    back = config_from_dict(json.loads(json.dumps(other.to_dict())))
    assert back == other and back.camera == camera and back.camera_mounting == (0.05, -0.01, 0.1)
    # a config written before the camera model: its field of view becomes the default camera's
    legacy = {k: v for k, v in config.to_dict().items() if k != "camera"}
    old = config_from_dict(legacy | {"camera_fov": math.radians(80.0)})
    assert old.camera.horizontal_fov == pytest.approx(math.radians(80.0))
    assert old.camera.mount_height == pinhole_camera().mount_height
    with pytest.raises(ValueError, match="mount_height"):
        SimulationConfig(camera=Camera(640, 480, 500.0, 500.0, 319.5, 239.5))
    with pytest.raises(ValueError, match="camera_mounting"):
        SimulationConfig(camera_mounting=(0.0, 0.0))
    with pytest.raises(ValueError, match="unknown"):
        config_from_dict({"sped": 1.0})
    with pytest.raises(ValueError, match="dropout"):
        SimulationConfig(dropout=1.5)
    with pytest.raises(ValueError, match="trajectory"):
        SimulationConfig(trajectory="circle")
    with pytest.raises(ValueError, match="max_speed"):
        SimulationConfig(max_speed=float("nan"))


def test_deterministic_for_a_seed():
    a, b = simulate(SimulationConfig(seed=7)), simulate(SimulationConfig(seed=7))
    c = simulate(SimulationConfig(seed=8))
    for x, y in ((a.controls.values, b.controls.values), (a.groundtruth.pose, b.groundtruth.pose)):
        assert np.array_equal(x, y)
    for name in ("t", "tag_id", "range", "bearing"):
        assert np.array_equal(getattr(a.detections, name), getattr(b.detections, name))
    assert a.meta.simulation == b.meta.simulation
    assert not np.allclose(a.groundtruth.pose[0], c.groundtruth.pose[0])
    assert len(a.detections.t) != len(c.detections.t) or not np.array_equal(
        a.detections.range, c.detections.range
    )


# --- true motion ------------------------------------------------------------------------------


@pytest.mark.parametrize("trajectory", ["square", "octagon"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_true_path_stays_inside_the_arena(trajectory, seed):
    log = simulate(SimulationConfig(trajectory=trajectory, seed=seed))
    assert np.all(SEED_ARENA.contains(log.groundtruth.pose, margin=0.1))


def test_without_motion_noise_the_true_path_is_the_believed_path():
    config = SimulationConfig(
        trajectory="square", wheel_noise_sigma=0.0, wheel_noise_fraction=0.0, start_error=(0, 0, 0)
    )
    log = simulate(config)
    believed = plan_commands(config, SEED_ARENA.nominal_start).believed
    diff = log.groundtruth.pose - believed
    assert np.abs(diff[:, :2]).max() < 1e-9 and np.abs(wrap(diff[:, 2])).max() < 1e-9


def test_wheel_noise_makes_the_true_path_drift():
    config = SimulationConfig(start_error=(0, 0, 0), seed=4)
    log = simulate(config)
    believed = plan_commands(config, SEED_ARENA.nominal_start).believed
    drift = np.linalg.norm(log.groundtruth.pose[-1, :2] - believed[-1, :2])
    assert 0.002 < drift < 0.2


def test_start_error_is_recorded_and_applied():
    explicit = simulate(SimulationConfig(start_error=(0.04, -0.02, 0.14)))
    assert np.allclose(explicit.groundtruth.pose[0], [-0.335, -0.395, 0.14])
    for log in (explicit, simulate(SimulationConfig(seed=5))):
        sim = log.meta.simulation
        first = log.groundtruth.pose[0]
        assert np.allclose(sim["true_start"], first, atol=1e-12)
        error = first - log.meta.nominal_start
        assert np.allclose(sim["start_error"], error, atol=1e-12)
    drawn = np.array(simulate(SimulationConfig(seed=5)).meta.simulation["start_error"])
    assert np.all(np.abs(drawn) < 5 * np.array([0.03, 0.03, 0.08])) and np.any(drawn != 0)
    # the robot is at rest while time passes after the last waypoint
    stop = explicit.groundtruth.pose[-20:]
    assert np.ptp(stop, axis=0).max() == 0.0


# --- the camera -------------------------------------------------------------------------------


def test_noiseless_detections_are_exact(noiseless):
    dr, db, _ = residuals(noiseless)
    assert np.abs(dr).max() < 1e-9 and np.abs(db).max() < 1e-9


def test_camera_frames_between_controls_see_the_pose_at_their_own_time():
    log = simulate(SimulationConfig(trajectory="square", camera_hz=15.0, **NOISELESS))
    assert np.allclose(log.detections.t * 15.0, np.rint(log.detections.t * 15.0))
    dr, db, _ = residuals(log)  # interpolation error only: 1/15 s frames fall between controls
    assert np.abs(dr).max() < 2e-3 and np.abs(db).max() < 2e-3


def test_exact_visible_set(noiseless):
    log, d = noiseless, noiseless.detections
    seen = {}
    for t, i in zip(d.t, d.tag_id, strict=True):
        seen.setdefault(round(t * 10), set()).add(int(i))
    frames = np.arange(0, round(log.controls.t[-1] * 10) + 1, 7)  # every 7th frame
    poses = pose_at(log, frames / 10.0)
    checked = 0
    for k, pose in zip(frames, poses, strict=True):
        for tag in SEED_ARENA.tags:
            ok, margin = expected_visible(pose, tag)
            if margin > 1e-6:  # no sharp verdict right on a boundary
                assert (tag.id in seen.get(k, set())) == ok, (k, tag.id)
                checked += 1
    assert checked > 500
    assert seen[0] == {1, 2}  # at the start, facing +x: tag 1 ahead, tag 2 at 62° incidence


def test_a_tag_too_close_is_cut_by_the_top_of_the_image():
    # facing tag 1 head-on: the horizontal field of view holds it at any distance, but closer
    # than about 0.34 m its outline's top (0.25 m high) leaves the image of a level camera
    # 0.12 m above the floor (25.5 degrees up at most)
    poses = np.array([[0.75 - d, -0.375, 0.0] for d in (0.28, 0.32, 0.36, 1.0)])
    seen = visible(poses, SEED_ARENA, SimulationConfig())[:, 1]
    assert seen.tolist() == [False, False, True, True]
    for pose, ok in zip(poses, seen, strict=True):
        assert expected_visible(pose, SEED_ARENA.tags[1])[0] == ok
    # tilted up by 5 degrees (a negative pitch), the camera sees it whole from 0.28 m
    tilted = SimulationConfig(camera=pinhole_camera(pitch=math.radians(-5.0)))
    assert visible(poses, SEED_ARENA, tilted)[:, 1].tolist() == [True] * 4


def test_a_tag_half_out_of_the_side_of_the_image_is_not_seen():
    # the tag's centre 30 degrees off the axis (inside the 32.5-degree half field of view) but
    # its outer edge beyond it: the centre-in-view rule said "seen", the whole-tag rule does not
    cam = np.array([0.0, -0.375])
    tag = SEED_ARENA.tags[1].position  # (0.75, -0.375), facing -x
    heading = math.radians(30.0)
    pose = np.array([[*(cam - [0.06 * math.cos(heading), 0.06 * math.sin(heading)]), heading]])
    assert not visible(pose, SEED_ARENA, SimulationConfig())[0, 1]
    assert not expected_visible(pose[0], SEED_ARENA.tags[1])[0]
    assert math.degrees(math.atan2(0.0, tag[0] - cam[0])) - 30.0 > -32.5


def test_tags_are_never_seen_from_behind():
    # two tags at one spot ahead of the robot: one faces it, the other faces away
    arena = Arena(
        0.75,
        (
            Tag(0, np.array([0.55, -0.375]), np.array([-1.0, 0.0])),
            Tag(1, np.array([0.55, -0.375]), np.array([1.0, 0.0])),
        ),
        SEED_ARENA.nominal_start,
    )
    log = simulate(SimulationConfig(**NOISELESS), arena=arena)
    assert log.meta.tag_map.keys() == {0, 1}
    counts = np.bincount(log.detections.tag_id, minlength=2)
    assert counts[0] > 20 and counts[1] == 0


def test_detection_noise_matches_its_sigmas(octagon):
    config = SimulationConfig(trajectory="octagon", seed=11, dropout=0.0, range_noise_sigma=0.03)
    for log, sigma_r in ((octagon, 0.02), (simulate(config), 0.03)):
        dr, db, _ = residuals(log)
        n = len(dr)
        assert n > 500
        assert abs(dr.std() / sigma_r - 1) < 0.2 and abs(db.std() / 0.02 - 1) < 0.2
        assert abs(dr.mean()) < 4 * sigma_r / math.sqrt(n)
        assert abs(db.mean()) < 4 * 0.02 / math.sqrt(n)


def test_proportional_range_noise():
    config = SimulationConfig(seed=2, range_noise_sigma=0.01, range_noise_fraction=0.05)
    dr, _, r = residuals(simulate(config))
    z = dr / np.sqrt(0.01**2 + (0.05 * r) ** 2)
    assert abs(z.std() - 1) < 0.15
    far = r > np.median(r)
    assert dr[far].std() > dr[~far].std()


def test_dropout_rate(noiseless):
    dropped = simulate(
        SimulationConfig(trajectory="octagon", seed=3, **{**NOISELESS, "dropout": 0.3})
    )
    n_all, n_kept = len(noiseless.detections.t), len(dropped.detections.t)
    rate = 1 - n_kept / n_all
    assert abs(rate - 0.3) < 4 * math.sqrt(0.3 * 0.7 / n_all)
    # dropped detections are a subset of the visible ones
    all_pairs = set(zip(noiseless.detections.t, noiseless.detections.tag_id, strict=True))
    assert set(zip(dropped.detections.t, dropped.detections.tag_id, strict=True)) <= all_pairs


def test_outliers_are_injected_at_their_rates_and_counted():
    config = SimulationConfig(
        trajectory="octagon",
        laps=4,
        seed=9,
        outlier_wrong_id_rate=0.2,
        outlier_range_rate=0.15,
        **NOISELESS,
    )
    log = simulate(config)
    dr, db, r = residuals(log)
    wrong_id = np.abs(db) > 1e-9  # the bearing of a misread tag points at another tag
    ratio = log.detections.range / r
    gross = ~wrong_id & (np.abs(dr) > 1e-9)
    n = len(dr)
    assert abs(wrong_id.mean() - 0.2) < 3 * math.sqrt(0.2 * 0.8 / n)
    assert abs(gross.sum() / (~wrong_id).sum() - 0.15) < 3 * math.sqrt(0.15 * 0.85 / n)
    assert np.all(
        (ratio[gross] >= 1.5 - 1e-9) & (ratio[gross] <= 3.0 + 1e-9)
        | (ratio[gross] >= 1 / 3 - 1e-9) & (ratio[gross] <= 1 / 1.5 + 1e-9)
    )
    counted = log.meta.simulation["outliers"]
    assert counted["wrong_id"] == wrong_id.sum()
    assert counted["range"] >= gross.sum()  # a misread tag may also carry a gross range
    assert len({(t, i) for t, i in zip(log.detections.t, log.detections.tag_id, strict=True)}) == n


def test_a_run_is_named_after_what_makes_it_differ_from_the_seeds():
    from ekfslam.sim.config import SEED_EXPERIMENTS, seed_experiment

    assert SimulationConfig(**SEED_EXPERIMENTS["octagon-2laps"]).name == "octagon-2laps"
    assert SimulationConfig(**SEED_EXPERIMENTS["square-2laps"]).name == "square-2laps"
    assert SimulationConfig(trajectory="octagon", seed=5).name == "octagon-2laps-seed5"
    other = SimulationConfig(
        trajectory="square",
        laps=1,
        seed=3,
        size=0.6,
        start_error=(-0.03, 0.04, 0.12),
        wheel_scale_sigma=0.01,
    )
    assert other.name == "square-1lap-seed3-size0.6-start-0.03,0.04,0.12-wheelscale0.01"
    # the seed's experiment with one thing changed is no longer the seed's experiment
    changed = {**SEED_EXPERIMENTS["octagon-2laps"], "dropout": 0.2}
    assert SimulationConfig(**changed).name == "octagon-2laps-seed2-start-0.04,0.04,0.13"
    # judged from run.json's simulation block, digits rounded as a writer might round them
    sim = {"config": SimulationConfig(**SEED_EXPERIMENTS["octagon-2laps"]).to_dict()}
    sim["config"]["max_incidence"] = round(sim["config"]["max_incidence"], 6)
    assert seed_experiment(sim) == "octagon"
    seed5 = SimulationConfig(trajectory="octagon", seed=5).to_dict()
    assert seed_experiment({"config": seed5}) is None
    assert seed_experiment(None) is None and seed_experiment({"seed": 2}) is None


def test_a_path_is_planned_once_for_the_runs_that_drive_it():
    """The controller's plan depends on the path and the controller only: runs that differ in
    the seed or a systematic error share it, read-only, and a different path gets its own."""
    a = realistic("square")
    start = SEED_ARENA.nominal_start
    plan = plan_commands(a, start)
    assert plan_commands(realistic("square", ("range scale",), seed=7), start) is plan
    assert plan_commands(realistic("square", size=0.6), start) is not plan
    with pytest.raises(ValueError, match="read-only"):
        plan.wheels[0, 0] = 1.0
    assert simulate(a).controls.values.flags.writeable  # the run's own copy
