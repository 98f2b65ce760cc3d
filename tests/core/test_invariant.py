"""The invariant EKF: its error map, its block form against the filter, its Cartesian reports."""

from __future__ import annotations

import numpy as np
import pytest

from ekfslam import pipeline
from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.invariant import (
    error_map,
    from_cartesian,
    noise_map,
    pose_error,
    retract,
    to_cartesian,
)
from ekfslam.core.models import (
    inverse_observation,
    inverse_observation_jacobians,
    motion_noise,
    observation_noise,
)
from ekfslam.core.noise import default_noise
from ekfslam.core.steps import new_landmark_step, predict_step
from ekfslam.errors import ConfigError
from ekfslam.logs.runlog import read_run
from ekfslam.places import seed_runs_dir
from ekfslam.teaching.reference import LiteralEKFSLAM

Q = observation_noise(0.05, 0.03)
R = np.diag([1e-4, 2e-4, 1e-3])
INVARIANT = FilterConfig(linearization="invariant", gate=None)


def test_pose_error_is_the_exact_log_of_retract_and_T_inverse_to_first_order():
    rng = np.random.default_rng(4)
    estimate = rng.normal(size=(6, 3)) * [2.0, 2.0, 1.0]
    xi = rng.normal(size=(6, 3)) * [0.5, 0.5, 0.8]
    xi[0] = 0.0  # the identity, where V(ξ_θ) is the identity
    xi[1, 2] = 1e-9  # the series branch near ξ_θ = 0
    truth = np.array([retract(m, x) for m, x in zip(estimate, xi, strict=True)])
    assert np.abs(pose_error(truth, estimate) - xi).max() < 1e-12
    small = 1e-7 * np.array([1.0, -2.0, 3.0])  # to first order ξ = T⁻¹ δ
    first = np.linalg.solve(error_map(estimate[2]), small)
    assert np.abs(pose_error(estimate[2] + small, estimate[2])[0] - first).max() < 1e-12


def test_the_error_map_and_its_inverse():
    mu = np.array([1.5, -2.0, 0.4, 3.0, 1.0, -1.0, 2.5])
    rng = np.random.default_rng(0)
    A = rng.normal(size=(7, 7))
    P = A @ A.T
    T = error_map(mu)
    np.testing.assert_allclose(to_cartesian(P, mu), T @ P @ T.T, rtol=0, atol=1e-12)
    np.testing.assert_allclose(from_cartesian(to_cartesian(P, mu), mu), P, rtol=0, atol=1e-12)
    # a small ξ moves the state by T ξ to first order: the error is second order
    xi = 1e-5 * rng.normal(size=7)
    moved = retract(mu, xi) - mu
    assert np.abs(moved - T @ xi).max() < 1e-9
    # the noise map is T⁻¹ at the pose rows: T A = F_xᵀ
    F = np.zeros((7, 3))
    F[:3] = np.eye(3)
    np.testing.assert_allclose(T @ noise_map(mu), F, rtol=0, atol=1e-15)


def test_a_rotation_of_the_whole_map_is_the_same_invariant_error_anywhere():
    # the unobservable direction (turn everything about the origin) is ξ = e₃ at any estimate:
    # what makes the invariant filter's Jacobians blind to where the estimate is along it
    for mu in (np.array([0.0, 0.0, 0.0, 1.0, 2.0]), np.array([-3.0, 4.0, 2.0, 5.0, -1.0])):
        turn = 1e-6
        c, s = np.cos(turn), np.sin(turn)
        rot = np.array([[c, -s], [s, c]])
        turned = np.concatenate([rot @ mu[:2], [mu[2] + turn], rot @ mu[3:]])
        xi = np.linalg.solve(error_map(mu), turned - mu)
        np.testing.assert_allclose(xi / turn, [0, 0, 1, 0, 0], rtol=0, atol=1e-5)


def two_filters():
    return [
        EKFSLAM([-2.0, -2.0, -0.4], np.diag([1e-4, 1e-4, 1e-4]), FilterConfig(gate=None)),
        EKFSLAM([-2.0, -2.0, -0.4], np.diag([1e-4, 1e-4, 1e-4]), INVARIANT),
    ]


def test_before_any_correction_the_invariant_covariance_is_the_standard_one():
    # propagation and initialisation are linear changes of coordinates of each other (T'⁻¹ G T
    # = I): until an update moves the means apart, the Cartesian covariances are equal
    filters = two_filters()
    for f in filters:
        f.predict([0.1, 0.0, 0.1], R)
        f.update(1, [1.0, 0.3], Q)
        f.update(2, [2.0, -0.3], Q)
        f.predict_many([[0.1, 0.02, 0.1]] * 3, [0.1] * 3, [1.0, 2.0, 3.0], R=R)
    standard, invariant = filters
    np.testing.assert_allclose(invariant.Sigma, standard.Sigma, rtol=0, atol=1e-15)
    np.testing.assert_allclose(invariant.mu, standard.mu, rtol=0, atol=1e-15)


def test_the_filter_steps_as_the_block_form():
    f = EKFSLAM([0.3, -0.2, 1.0], np.diag([1e-4, 1e-4, 1e-4]), INVARIANT)
    mu, P = f.mu.copy(), f.invariant_covariance
    for k, z in enumerate([[1.0, 0.3], [2.0, -0.3], [1.5, 2.0]]):
        f.update(k, z, Q)
        mu, P = new_landmark_step(mu, P, z, Q, invariant=True)
    np.testing.assert_allclose(f.invariant_covariance, P, rtol=0, atol=1e-15)
    for u in ([0.1, 0.0, 0.2], [0.05, 0.01, -0.3]):
        f.predict(u, R)
        mu, P = predict_step(mu, P, u, R, invariant=True)
    np.testing.assert_allclose(f.mu, mu, rtol=0, atol=1e-14)
    np.testing.assert_allclose(f.invariant_covariance, P, rtol=0, atol=1e-15)


def test_every_report_of_the_invariant_filter_is_cartesian():
    f = EKFSLAM([1.0, 2.0, 0.5], np.diag([1e-3, 2e-3, 4e-3]), INVARIANT)
    # the start covariance is taken as Cartesian
    np.testing.assert_allclose(f.pose_covariance, np.diag([1e-3, 2e-3, 4e-3]), atol=1e-15)
    f.update(7, [1.5, 0.4], Q)
    f.predict([0.2, 0.0, 0.3], R)
    f.update(7, [1.3, 0.2], Q)
    Sigma, h = f.Sigma, f.history()
    np.testing.assert_allclose(Sigma, to_cartesian(f.invariant_covariance, f.mu), atol=1e-15)
    np.testing.assert_allclose(f.pose_covariance, Sigma[:3, :3], rtol=0, atol=1e-15)
    np.testing.assert_allclose(h.pose_cov[-1], Sigma[:3, :3], rtol=0, atol=1e-15)
    np.testing.assert_allclose(h.pose_cov[1], h.pose_cov[1].T, rtol=0, atol=0)
    _, cov = f.landmark(7)
    np.testing.assert_allclose(cov, Sigma[3:5, 3:5], rtol=0, atol=1e-15)
    np.testing.assert_allclose(h.obs_landmark_cov[-1], cov, rtol=0, atol=1e-15)
    assert not np.allclose(f.invariant_covariance, Sigma)  # they are different coordinates
    # and back: the NEES in ξ (`analysis.consistency.pose_nees_xi`) scores against the filter's P
    P = f.invariant_covariance[:3, :3]
    np.testing.assert_allclose(from_cartesian(h.pose_cov[-1], h.pose[-1]), P, rtol=0, atol=1e-15)


def test_only_the_invariant_filter_has_an_invariant_covariance():
    with pytest.raises(AttributeError, match="invariant"):
        _ = EKFSLAM([0.0, 0.0, 0.0]).invariant_covariance
    with pytest.raises(ConfigError, match=r"'invariant'.*got 'iekf'"):
        FilterConfig(linearization="iekf")


def test_the_heading_noise_owed_to_the_map_is_in_every_report():
    # the map block's share of the prediction noise waits for the next correction's pass;
    # what is read before (a rejected sighting's record, a landmark, Σ) includes it
    f = EKFSLAM(
        [1.0, 2.0, 0.5], np.diag([1e-4, 1e-4, 1e-4]), FilterConfig(linearization="invariant")
    )
    twin = EKFSLAM(
        [1.0, 2.0, 0.5], np.diag([1e-4, 1e-4, 1e-4]), FilterConfig(linearization="invariant")
    )
    for g in (f, twin):
        g.update(1, [1.5, 0.4], Q)
        g.update(2, [2.5, -0.4], Q)
        g.predict_many([[0.1, 0.0, 0.2]] * 4, [0.1] * 4, [1.0, 2.0, 3.0, 4.0], R=R)
    assert f.update(1, [4.0, 2.0], Q).label == "rejected"  # far outside the gate
    _, cov = f.landmark(1)
    np.testing.assert_allclose(f.history().obs_landmark_cov[-1], cov, rtol=0, atol=1e-15)
    _ = twin.Sigma  # settles what is owed at once: the same state as correcting with it owed
    for g in (f, twin):
        g.update(2, [2.3, -0.6], Q)
    np.testing.assert_allclose(f.Sigma, twin.Sigma, rtol=0, atol=1e-15)
    np.testing.assert_allclose(f.mu, twin.mu, rtol=0, atol=1e-15)


def test_the_invariant_filter_replays_a_seed_run_as_the_literal_reference():
    # the seed's octagon, event by event: the compiled filter (batched predictions, the owed
    # map-block noise) against the literal F_x form (a full-size step each), to 1e-9
    run = read_run(seed_runs_dir() / "octagon-2laps")
    s = pipeline.schedule(run, default_noise(run))
    upto, us, dts, ends, M, R_fixed = s.upto, s.u, s.dt, s.t, s.M, s.R
    ids, times, zs, Q_run = s.ids, s.times, s.z, s.Q
    config = FilterConfig(linearization="invariant")
    start = run.meta.nominal_start
    fast, slow = EKFSLAM(start, None, config), LiteralEKFSLAM(start, None, config)

    done = 0
    for i, p in enumerate(upto):
        if p > done:
            fast.predict_many(us[done:p], dts[done:p], ends[done:p], M, R_fixed)
            for k in range(done, p):
                slow.predict(us[k], R_fixed if M is None else motion_noise(slow.mu, M * dts[k]))
            done = p
        assert fast.update(ids[i], zs[i], Q_run, times[i]) == slow.update(ids[i], zs[i], Q_run)
    assert fast.counts.accepted > 500 and fast.n_landmarks == 8
    np.testing.assert_allclose(fast.mu, slow.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.Sigma, slow.cartesian_Sigma, rtol=0, atol=1e-9)


def test_eq_12_is_exact_to_first_order_in_xi_where_it_is_not_in_cartesian():
    # A 4 m sighting (σr, σφ 0.02) from a pose known to σp 0.05 m, σθ 0.05 rad: the Monte Carlo
    # covariance of the exact inverse observation against the linear one of eq. (12). In the
    # invariant error the heading's part is exact (ξ_m = ξ_p + V⁻¹R(ξθ) R(θ̂)(g(z-v) - g(z))),
    # so there is nothing left for a second-order or unscented initialisation to correct.
    rng = np.random.default_rng(0)
    n, pose, z = 400_000, np.array([1.0, 2.0, 0.7]), np.array([4.0, 0.3])
    sr = sf = 0.02
    sp, sth = 0.05, 0.05
    v = rng.normal(0.0, [sr, sf], (n, 2))
    Qz = np.diag([sr**2, sf**2])
    G_p, G_z = inverse_observation_jacobians(pose, z)
    m_hat = inverse_observation(pose, z)

    def true_landmark(p, th):
        r, phi = (z - v).T
        return p + r[:, None] * np.column_stack([np.cos(th + phi), np.sin(th + phi)])

    # invariant: the true pose is exp(ξ) X̂, the landmark's ξ_m from m = R(ξθ) m̂ + V(ξθ) ξ_m
    xi = rng.normal(0.0, [sp, sp, sth], (n, 3))
    poses = np.array([retract(pose, x) for x in xi[:2000]])  # retract's branch checked below
    w = xi[:, 2]
    c, s = np.cos(w), np.sin(w)
    va, vb = np.sin(w) / w, (1.0 - c) / w
    p = np.column_stack(
        [
            c * pose[0] - s * pose[1] + va * xi[:, 0] - vb * xi[:, 1],
            s * pose[0] + c * pose[1] + vb * xi[:, 0] + va * xi[:, 1],
        ]
    )
    np.testing.assert_allclose(p[:2000], poses[:, :2], atol=1e-12)
    m = true_landmark(p, pose[2] + w)
    d = m - np.column_stack([c * m_hat[0] - s * m_hat[1], s * m_hat[0] + c * m_hat[1]])
    xi_m = np.column_stack([va * d[:, 0] + vb * d[:, 1], -vb * d[:, 0] + va * d[:, 1]])
    xi_m /= (va * va + vb * vb)[:, None]
    linear = sp**2 * np.eye(2) + G_z @ Qz @ G_z.T  # ξ_m = ξ_p + G_z δz
    ratio = np.linalg.eigvalsh(np.linalg.solve(linear, np.cov(xi_m.T)))
    assert np.all(np.abs(ratio - 1.0) < 0.006)  # measured 0.9993 and 0.9999
    # Cartesian: the standard filter's eq. (12) with the same pose and sighting noise
    e = rng.normal(0.0, [sp, sp, sth], (n, 3))
    m = true_landmark(pose[:2] + e[:, :2], pose[2] + e[:, 2])
    linear = G_p @ np.diag([sp, sp, sth]) ** 2 @ G_p.T + G_z @ Qz @ G_z.T
    ratio = np.linalg.eigvalsh(np.linalg.solve(linear, np.cov(m.T)))
    assert ratio.max() > 1.012  # measured 1.021: the linear covariance is too small
