"""Replay order: predictions up to each detection's time, then the correction."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.filter.history import OBSERVE, PREDICT
from ekfslam.core.kinematics import MecanumGeometry, twist_to_wheels
from ekfslam.core.noise import NoiseConfig
from ekfslam.logs.runlog import Controls, Detections, GroundTruth, RunLog, RunMeta
from ekfslam.pipeline import replay, schedule
from ekfslam.schedule import feed


def make_run(ctrl_t, twist, det_t, det_id, det_z, kind="twist", robot=None):
    values = np.asarray(twist, dtype=float)
    if kind == "wheels":
        values = twist_to_wheels(values, robot)
    det_z = np.asarray(det_z, dtype=float).reshape(-1, 2)
    return RunLog(
        meta=RunMeta(name="hand", source="recorded", nominal_start=np.zeros(3), robot=robot),
        controls=Controls(t=np.asarray(ctrl_t, float), kind=kind, values=values),
        detections=Detections(
            t=np.asarray(det_t, float),
            tag_id=np.asarray(det_id, dtype=np.int64),
            range=det_z[:, 0],
            bearing=det_z[:, 1],
        ),
    )


def test_predicts_up_to_each_detection_then_corrects():
    run = make_run(
        ctrl_t=[0.0, 1.0, 2.0],
        twist=[[0.1, 0.0, 0.0], [0.0, 0.0, 0.5], [0.0, 0.0, 0.0]],
        det_t=[0.5, 1.5, 1.5, 2.5],
        det_id=[1, 1, 2, 2],
        det_z=[[1.0, 0.0], [0.95, -0.25], [1.0, 1.0], [1.0, 1.0]],
    )
    h = replay(run, NoiseConfig(sigma_range=1e3, sigma_bearing=1e3)).history
    kinds = ["P" if e == PREDICT else "O" for e in h.event]
    assert "".join(kinds) == "POPPOOPPO"
    np.testing.assert_allclose(h.t, [0.5, 0.5, 1.0, 1.5, 1.5, 1.5, 2.0, 2.5, 2.5])
    # the pose used by each correction is the prediction up to the detection's time
    first_obs = np.flatnonzero(h.event == OBSERVE)[0]
    assert h.pose[first_obs - 1] == pytest.approx([0.05, 0.0, 0.0], abs=1e-12)
    second = np.flatnonzero(h.event == OBSERVE)[1]
    assert h.pose[second - 1] == pytest.approx([0.1, 0.0, 0.25], abs=1e-12)
    np.testing.assert_array_equal(h.obs_t, [0.5, 1.5, 1.5, 2.5])


def test_detections_before_the_first_control_are_used_standing_still():
    run = make_run(
        ctrl_t=[1.0, 2.0],
        twist=[[0.2, 0.0, 0.0], [0.0, 0.0, 0.0]],
        det_t=[0.2, 1.5],
        det_id=[4, 4],
        det_z=[[1.0, 0.0], [0.9, 0.0]],
    )
    h = replay(run).history
    assert h.event[0] == OBSERVE and h.t[0] == 0.2
    assert h.pose[0].tolist() == [0.0, 0.0, 0.0]
    # after: predict 1.0 -> 1.5 with the first row, observe, predict 1.5 -> 2.0
    assert h.pose[np.flatnonzero(h.event == OBSERVE)[1] - 1][0] == pytest.approx(0.1)
    assert h.t[-1] == 2.0


def test_replay_equals_stepping_the_filter_by_hand():
    rng = np.random.default_rng(0)
    ctrl_t = np.cumsum(rng.uniform(0.02, 0.08, 200))
    twist = np.column_stack(
        [rng.uniform(0, 0.2, 200), rng.uniform(-0.05, 0.05, 200), rng.uniform(-0.5, 0.5, 200)]
    )
    det_t = np.sort(rng.uniform(ctrl_t[0], ctrl_t[-1], 60))
    det_id = rng.integers(0, 5, 60)
    det_z = np.column_stack([rng.uniform(0.5, 2.0, 60), rng.uniform(-1, 1, 60)])
    run = make_run(ctrl_t, twist, det_t, det_id, det_z)
    noise = NoiseConfig(sigma_x=0.02, sigma_y=0.01, sigma_theta=0.03)
    result = replay(run, noise, FilterConfig(gate=None))

    ekf = EKFSLAM(np.zeros(3), config=FilterConfig(gate=None))
    D = noise.motion_density()
    events = sorted(
        [(t, 0, k) for k, t in enumerate(ctrl_t)] + [(t, -1, i) for i, t in enumerate(det_t)]
    )  # at equal times a detection is used after predicting up to it; controls change after
    t_now, k = ctrl_t[0], 0
    for t, kind, idx in events:
        if t > t_now and (kind == -1 or idx > 0):
            dt = t - t_now
            c, s = math.cos(ekf.mu[2]), math.sin(ekf.mu[2])
            V = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
            ekf.predict(twist[k] * dt, V @ (D * dt) @ V.T)
            t_now = t
        if kind == -1:
            ekf.update(int(det_id[idx]), det_z[idx], noise.Q)
        else:
            k = idx
    np.testing.assert_allclose(result.mu, ekf.mu, atol=1e-12)
    np.testing.assert_allclose(result.Sigma, ekf.Sigma, atol=1e-12)


def test_motion_noise_adds_up_the_same_however_intervals_are_split():
    """A random walk: splitting a control interval at a detection does not change the total."""
    base = dict(ctrl_t=[0.0, 2.0], twist=[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    far = [[1e3, 0.0]]  # a landmark far away: its update barely informs the pose
    whole = replay(make_run(**base, det_t=[2.0], det_id=[1], det_z=far), NoiseConfig())
    split = replay(
        make_run(**base, det_t=[0.3, 1.1, 2.0], det_id=[1, 2, 3], det_z=far * 3), NoiseConfig()
    )
    P_whole = whole.history.pose_cov[np.flatnonzero(whole.history.event == PREDICT)[-1]]
    P_split = split.history.pose_cov[np.flatnonzero(split.history.event == OBSERVE)[0] - 1]
    expected = NoiseConfig().motion_density() * 2.0
    np.testing.assert_allclose(P_whole, expected, rtol=1e-12)
    # the split run reaches t = 0.3 first: 0.3 s worth of noise
    np.testing.assert_allclose(P_split, NoiseConfig().motion_density() * 0.3, rtol=1e-12)


def test_wheel_controls_are_turned_into_body_twists():
    geometry = MecanumGeometry()
    twist = [[0.1, 0.05, 0.3], [0.0, 0.0, 0.0]]
    run = make_run([0.0, 1.0], twist, [], [], np.zeros((0, 2)), kind="wheels", robot=geometry)
    np.testing.assert_allclose(run.control_twist(), twist, atol=1e-12)
    h = replay(run).history
    assert h.pose[-1] == pytest.approx([0.1, 0.05, 0.3])


def test_fixed_R_per_step_is_the_seeds_way():
    R = ((1e-4, 0.0, 0.0), (0.0, 1e-4, 0.0), (0.0, 0.0, 1e-5))
    run = make_run([0.0, 0.1, 0.2, 0.3], np.zeros((4, 3)), [], [], np.zeros((0, 2)))
    h = replay(run, NoiseConfig(R_per_step=R)).history
    np.testing.assert_allclose(h.pose_cov[-1], 3 * np.asarray(R), rtol=1e-12)
    with pytest.raises(ValueError, match="positive semi-definite"):
        NoiseConfig(R_per_step=((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)))


def test_ate_uses_ground_truth_only_where_it_exists():
    from ekfslam.analysis.evaluation import ate_rmse

    run = make_run([0.0, 1.0, 2.0], [[0.1, 0, 0], [0.1, 0, 0], [0, 0, 0]], [], [], np.zeros((0, 2)))
    result = replay(run)
    # truth runs 1 cm to the left of the estimate, and ends early at t = 1
    gt = GroundTruth(t=np.array([0.0, 1.0]), pose=np.array([[0.0, 0.01, 0.0], [0.1, 0.01, 0.0]]))
    assert ate_rmse(result, gt) == pytest.approx(0.01, rel=1e-9)


@pytest.fixture(scope="module")
def square_run() -> RunLog:
    from ekfslam.sim.simulation import SimulationConfig, simulate

    return simulate(SimulationConfig(trajectory="square", laps=1, seed=1))


def test_pathological_noise_gives_singular_updates_with_a_warning_not_refusals(square_run):
    from ekfslam.analysis.evaluation import summarize

    zero_R = ((0.0, 0.0, 0.0),) * 3
    cases = [
        NoiseConfig(R_per_step=zero_R, sigma_range=1e-160, sigma_bearing=1e-160),  # S underflows
        NoiseConfig(sigma_x=1e150),  # S overflows
    ]
    for noise in cases:
        with pytest.warns(RuntimeWarning, match="singular or not finite"):
            result = replay(square_run, noise)
        c = result.counts
        assert c.refused == 0 and c.singular > 200 and c.initialised == 8
        summary = summarize(square_run, result)
        assert summary.singular == c.singular
        assert summary.as_dict()["updates"]["singular"] == c.singular


def test_a_sigma_whose_square_underflows_or_overflows_is_refused() -> None:
    with pytest.raises(ValueError, match="underflow"):
        NoiseConfig(sigma_range=1e-170)
    with pytest.raises(ValueError, match="overflows"):
        NoiseConfig(sigma_theta=1e160)


def test_a_state_that_becomes_non_finite_is_an_error_saying_when(square_run) -> None:
    from ekfslam.pipeline import NonFiniteStateError

    with pytest.raises(NonFiniteStateError, match=r"non-finite at t = \d+\.\d+ s \(prediction"):
        replay(square_run, NoiseConfig(sigma_x=1e154))


def test_a_huge_start_pose_through_the_api_is_an_error_not_a_nan_table(square_run) -> None:
    for pose in [(1e308, 0.0, 0.0), (0.0, 0.0, math.nan), (0.0, 0.0, 90.0)]:
        with pytest.raises(ValueError, match="not a plausible"):
            replay(square_run, start=pose)


# --- one Q per detection through the feed loop (issue 26; the lead's rewrite keeps this) ------


def _random_run(seed: int, n_det: int = 60) -> RunLog:
    rng = np.random.default_rng(seed)
    ctrl_t = np.cumsum(rng.uniform(0.02, 0.08, 200))
    twist = np.column_stack(
        [rng.uniform(0, 0.2, 200), rng.uniform(-0.05, 0.05, 200), rng.uniform(-0.5, 0.5, 200)]
    )
    det_t = np.sort(rng.uniform(ctrl_t[0], ctrl_t[-1], n_det))
    det_id = rng.integers(0, 5, n_det)
    det_z = np.column_stack([rng.uniform(0.5, 2.0, n_det), rng.uniform(-1, 1, n_det)])
    return make_run(ctrl_t, twist, det_t, det_id, det_z)


def test_feed_gives_each_detection_its_own_q_when_given_one_per_detection() -> None:
    """`feed` with Q of shape (N, 2, 2) updates detection i with Q[i]: the same state as a
    hand-written loop over `EKFSLAM.update` with those Q; N copies of one Q give the same state
    as that Q alone (to round-off: the arithmetic is the same, the addresses are not)."""
    run = _random_run(3)
    noise = NoiseConfig(sigma_range=0.05, sigma_bearing=0.02)
    steps = schedule(run, noise)
    upto, us, dts, ends, M, R = steps.upto, steps.u, steps.dt, steps.t, steps.M, steps.R
    det_id, det_time, det_z, Q = steps.ids, steps.times, steps.z, steps.Q
    n = len(det_id)
    each = np.array([np.diag([(0.01 + 0.02 * k) ** 2, (0.005 * (k + 1)) ** 2]) for k in range(n)])
    fed = EKFSLAM(run.meta.nominal_start)
    feed(fed, dataclasses.replace(steps, Q=each))
    by_hand = EKFSLAM(run.meta.nominal_start)
    done = 0
    for i, p in enumerate(upto):
        if p > done:
            by_hand.predict_many(us[done:p], dts[done:p], ends[done:p], M, R)
            done = p
        by_hand.update(det_id[i], det_z[i], each[i], det_time[i])
    if done < len(us):
        by_hand.predict_many(us[done:], dts[done:], ends[done:], M, R)
    # the same numbers by two routes: equal to round-off (the Q's sit at other addresses, and a
    # small product may round its last bit by its operands' alignment on another CPU)
    np.testing.assert_allclose(fed.mu, by_hand.mu, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(fed.Sigma, by_hand.Sigma, rtol=1e-12, atol=1e-18)
    one, copies = EKFSLAM(run.meta.nominal_start), EKFSLAM(run.meta.nominal_start)
    feed(one, steps)
    feed(copies, dataclasses.replace(steps, Q=np.repeat(Q[None], n, 0)))
    np.testing.assert_allclose(one.mu, copies.mu, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(one.Sigma, copies.Sigma, rtol=1e-12, atol=1e-18)
    assert np.abs(fed.mu - one.mu).max() > 1e-6  # the Q given did change the estimate
