"""Tests of ekfslam.teaching.lessons: the plumbing the classroom notebooks stand on."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ekfslam import EKFSLAM, FilterConfig, NoiseConfig, SimulationConfig, read_run, replay, simulate
from ekfslam.analysis.evaluation import summarize
from ekfslam.errors import EkfSlamError
from ekfslam.teaching.lessons import (
    check_answer,
    filter_frame_transform,
    landmark_slots,
    lap_statistics,
    lap_times,
    position_errors,
    prior_before,
    replay_until,
    revisits,
    size_sweep,
    table1_markdown,
    tags_in_filter_frame,
    truncate,
    truth_in_filter_frame,
    update_steps,
    without_detections,
)
from ekfslam.teaching.reference import LiteralEKFSLAM

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


@pytest.fixture(scope="module")
def square():
    return read_run(RUNS / "square-2laps")


@pytest.fixture(scope="module")
def square_result(square):
    return replay(square)


# --- pieces of a run ----------------------------------------------------------------------------


def test_dead_reckoning_heading_variance_is_the_noise_density_times_the_duration(square) -> None:
    noise = NoiseConfig()
    dead = replay(without_detections(square), noise)
    assert dead.counts.accepted == dead.counts.initialised == 0
    assert len(dead.landmarks) == 0
    duration = square.controls.t[-1] - square.controls.t[0]
    # R = V M dt Vᵀ with V's θ row (0, 0, 1): the heading variance is σθ² times the time driven
    assert dead.history.pose_cov[-1, 2, 2] == pytest.approx(noise.sigma_theta**2 * duration)


def test_truncate_keeps_what_happened_up_to_the_cut_and_holds_the_last_control(square) -> None:
    cut = truncate(square, 10.02)
    assert cut.controls.t[-1] == 10.02
    assert cut.controls.t[-2] == pytest.approx(10.0)
    np.testing.assert_array_equal(cut.controls.values[-1], cut.controls.values[-2])
    assert cut.detections.t.max() <= 10.02
    assert len(cut.detections.t) == np.count_nonzero(square.detections.t <= 10.02)
    assert cut.groundtruth.t.max() <= 10.02
    assert len(truncate(square, 10.02, max_detections=5).detections.t) == 5
    with pytest.raises(ValueError, match="before the first control"):
        truncate(square, -1.0)


def test_replay_until_a_detection_time_is_the_full_replay_at_that_moment(
    square, square_result
) -> None:
    h = square_result.history
    t_cut = float(square.detections.t[300])
    part = replay_until(square, t_cut)
    last = np.flatnonzero(h.t <= t_cut)[-1]  # the full replay's last event at or before the cut
    np.testing.assert_array_equal(part.mu[:3], h.pose[last])
    np.testing.assert_array_equal(part.Sigma[:3, :3], h.pose_cov[last])
    assert part.history.t[-1] == t_cut


def test_replay_until_the_end_is_the_full_replay(square, square_result) -> None:
    whole = replay_until(square, float(square.controls.t[-1]))
    np.testing.assert_allclose(whole.mu, square_result.mu, atol=1e-12)
    np.testing.assert_allclose(whole.Sigma, square_result.Sigma, atol=1e-12)


def test_landmark_slots_follow_the_order_of_first_sightings(square, square_result) -> None:
    ids = square.detections.tag_id
    _, first = np.unique(ids, return_index=True)
    expected = [int(ids[i]) for i in sorted(first)]
    assert landmark_slots(square_result) == expected


def test_landmark_slots_detect_a_result_whose_order_is_not_the_state_order(square_result) -> None:
    shuffled = dict(reversed(list(square_result.landmarks.items())))
    with pytest.raises(EkfSlamError, match="not in slot"):
        landmark_slots(replace(square_result, landmarks=shuffled))


# --- the filter's frame -------------------------------------------------------------------------


def test_noise_free_dead_reckoning_matches_the_truth_in_the_filter_frame() -> None:
    config = SimulationConfig(
        laps=1, seed=5, wheel_noise_sigma=0.0, wheel_noise_fraction=0.0,
        start_error=(0.05, -0.03, 0.1),
    )  # fmt: skip
    run = simulate(config)
    T = filter_frame_transform(run)
    framed = truth_in_filter_frame(run)
    np.testing.assert_allclose(framed.pose[0], run.meta.nominal_start, atol=1e-12)
    _, err = position_errors(run, replay(without_detections(run)).history)
    # the filter integrates eq. (6) in Euler steps, the simulator exact arcs: sub-millimetre apart
    assert err.max() < 1e-3
    # in the world frame the same path is off by about the 5.8 cm placement error
    world_err = np.hypot(*(run.groundtruth.pose[0, :2] - run.meta.nominal_start[:2]))
    assert world_err == pytest.approx(math.hypot(0.05, 0.03))
    tags = tags_in_filter_frame(run)
    a, b = run.meta.tag_map[0], run.meta.tag_map[5]
    assert np.hypot(*(tags[0] - tags[5])) == pytest.approx(np.hypot(*(a - b)))
    assert T[2] == pytest.approx(-0.1)


def test_the_filter_frame_needs_ground_truth(square) -> None:
    with pytest.raises(EkfSlamError, match="no ground truth"):
        filter_frame_transform(replace(square, groundtruth=None))


# --- one correction -----------------------------------------------------------------------------


def test_update_steps_against_a_hand_computed_scalar_case() -> None:
    # robot known exactly at the origin facing +x, landmark at (2, 0) with variance v on each axis
    v, q_r, q_phi = 0.04, 0.01, 0.0025
    mu = np.array([0.0, 0.0, 0.0, 2.0, 0.0])
    Sigma = np.diag([0.0, 0.0, 0.0, v, v])
    z = np.array([2.1, 0.05])
    steps = update_steps(mu, Sigma, 0, z, np.diag([q_r, q_phi]))
    np.testing.assert_allclose(steps.z_hat, [2.0, 0.0])
    np.testing.assert_allclose(steps.H, [[-1, 0, 0, 1, 0], [0, -0.5, -1, 0, 0.5]])
    # range moves the landmark along x, bearing along y (lever arm r = 2)
    gain_x, gain_y = v / (v + q_r), 0.25 * v / (0.25 * v + q_phi)
    np.testing.assert_allclose(steps.mu_post[3:], [2.0 + gain_x * 0.1, 2.0 * gain_y * 0.05])
    np.testing.assert_allclose(
        np.diag(steps.Sigma_joseph)[3:], [v * (1 - gain_x), v * (1 - gain_y)]
    )
    np.testing.assert_allclose(steps.Sigma_seed, steps.Sigma_joseph, atol=1e-15)
    assert steps.nis == pytest.approx(0.1**2 / (v + q_r) + 0.05**2 / (0.25 * v + q_phi))


def test_update_steps_agree_with_the_literal_reference_filter() -> None:
    pose, P0 = [0.1, -0.2, 0.4], np.diag([1e-3, 2e-3, 5e-3])
    Q = np.diag([0.03**2, 0.02**2])
    literal = LiteralEKFSLAM(pose, P0)
    literal.update(3, [1.0, 0.3], Q)
    literal.update(8, [0.7, -0.6], Q)
    literal.predict([0.05, 0.01, 0.1], np.diag([1e-4, 1e-4, 4e-4]))
    steps = update_steps(literal.mu, literal.Sigma, 1, [0.72, -0.75], Q)
    literal.update(8, [0.72, -0.75], Q)
    np.testing.assert_allclose(steps.mu_post, literal.mu, atol=1e-14)
    np.testing.assert_allclose(steps.Sigma_joseph, literal.Sigma, atol=1e-14)
    assert steps.K.shape == (7, 2)


def test_prior_before_and_update_steps_reproduce_the_replay(square) -> None:
    k = 309  # tag 1 seen again at 28.2 s
    prior = prior_before(square, k)
    slots = landmark_slots(prior)
    z = [square.detections.range[k], square.detections.bearing[k]]
    steps = update_steps(prior.mu, prior.Sigma, slots.index(int(square.detections.tag_id[k])),
                         z, NoiseConfig().Q)  # fmt: skip
    after = replay(truncate(square, float(square.detections.t[k]), max_detections=k + 1))
    np.testing.assert_allclose(steps.mu_post, after.mu, atol=1e-12)
    np.testing.assert_allclose(steps.Sigma_joseph, after.Sigma, atol=1e-12)
    # the prior is predicted to the sighting's time but has not used it
    assert prior.history.t[-1] == square.detections.t[k]
    assert prior.counts.accepted + prior.counts.initialised == k


# --- laps and sweeps ----------------------------------------------------------------------------


def test_lap_times_are_every_fourth_waypoint_of_the_square(square) -> None:
    times = square.meta.simulation["waypoint_times"]
    np.testing.assert_array_equal(lap_times(square), [times[4], times[8]])
    with pytest.raises(EkfSlamError, match="not a simulated run"):
        lap_times(replace(square, meta=replace(square.meta, simulation=None)))


def test_lap_statistics_of_the_square_run(square) -> None:
    laps = lap_statistics(square)
    assert [s.lap for s in laps] == [1, 2]
    assert laps[0].t_start == 0.0 and laps[1].t_start == laps[0].t_end
    assert all(s.landmarks == 8 for s in laps)
    assert laps[1].map_sd < laps[0].map_sd  # the seed's "driving multiple times"
    for s in laps:
        assert 0 < s.map_error < 0.05 and 0 < s.position_rmse < 0.05
        assert s.map_error <= s.map_error_unaligned  # the fit can only lower the mean distance


def test_revisits_find_sightings_after_a_gap() -> None:
    ekf = EKFSLAM([0.0, 0.0, 0.0])
    Q = np.diag([0.01, 0.01])
    for t, i in ((0.0, 1), (1.0, 2), (5.0, 1), (20.0, 1), (30.0, 2), (31.0, 2)):
        ekf.update(i, [1.0, 0.5 * i], Q, t=t)
    times, ids = revisits(ekf.history(), gap=10.0)
    np.testing.assert_array_equal(times, [20.0, 30.0])
    np.testing.assert_array_equal(ids, [1, 2])


def test_size_sweep_gives_one_scored_point_per_run() -> None:
    points = size_sweep(("octagon",), (0.7,), seeds=(3,), laps=1)
    assert len(points) == 1
    p = points[0]
    assert (p.trajectory, p.size, p.seed, p.landmarks) == ("octagon", 0.7, 3, 8)
    assert 0 < p.map_error < 0.05 and 0 < p.position_rmse < 0.05


# --- tables and exercises -----------------------------------------------------------------------


def test_table1_markdown_puts_each_run_beside_the_seed(square, square_result) -> None:
    summary = summarize(square, square_result)
    seed = {"square": (-0.02, 0.056, 0.142, 0.153)}
    table = table1_markdown({"square": summary}, seed).splitlines()
    assert len(table) == 4
    a = summary.alignment
    assert table[2].startswith("| square, this simulation")
    assert f"{a.x0:.3f}" in table[2] and f"{a.mean_error:.3f}" in table[2]
    assert table[3] == "| square, seed report (real robot) | -0.020 | 0.056 | 0.142 | 0.153 |"
    with pytest.raises(EkfSlamError, match="no alignment"):
        table1_markdown({"square": replace(summary, alignment=None)}, seed)


def test_check_answer(capsys) -> None:
    assert check_answer(None, 1.0) is False
    assert "Not answered yet" in capsys.readouterr().out
    assert check_answer([1.0, 2.0000001], [1.0, 2.0]) is True
    assert "Right" in capsys.readouterr().out
    assert check_answer([1.0, 2.1], [1.0, 2.0]) is False
    assert "off by up to 0.1" in capsys.readouterr().out
    assert check_answer([1.0], [1.0, 2.0]) is False
    assert "shape" in capsys.readouterr().out
    assert check_answer("seven", 7.0) is False
    assert "not a number" in capsys.readouterr().out


def test_filter_config_seed_init_is_exercised_by_update_steps_like_the_notebook() -> None:
    # notebook 05: with V = 1e6 the seed's init is within 1e-9 of the inverse-observation init
    pose, P0, Q = np.array([-0.4, -0.4, 0.0]), np.diag([4e-4, 4e-4, 2.5e-3]), np.diag([9e-4, 9e-4])
    z = np.array([1.0, 0.3])
    exact = EKFSLAM(pose, P0, FilterConfig(init="inverse"))
    exact.update(0, z, Q)
    m = exact.mu[3:]
    Sigma = np.block([[P0, np.zeros((3, 2))], [np.zeros((2, 3)), 1e6 * np.eye(2)]])
    steps = update_steps(np.concatenate([pose, m]), Sigma, 0, z, Q)
    assert np.abs(steps.Sigma_joseph - exact.Sigma).max() < 1e-9
    np.testing.assert_allclose(steps.mu_post, exact.mu, atol=1e-12)
