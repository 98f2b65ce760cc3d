"""The iterated update (`FilterConfig.iterations`, `ekfslam.core.filter.iterated`): Gauss-Newton.

Held to the literal full-size reference (`ekfslam.teaching.reference`) on the seed's octagon, and
to what Gauss-Newton must reach: the converged standard update is a stationary point of the MAP
cost of one observation, checked by finite differences of that cost.
"""

from __future__ import annotations

import numpy as np
import pytest

from ekfslam import pipeline
from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.models import motion_noise, observation, observation_noise
from ekfslam.core.noise import default_noise
from ekfslam.errors import ConfigError
from ekfslam.geometry import wrap_angle
from ekfslam.logs.runlog import read_run
from ekfslam.places import seed_runs_dir
from ekfslam.teaching.reference import LiteralEKFSLAM

Q = observation_noise(0.05, 0.03)


def _one_landmark(config: FilterConfig, heading_variance: float = 0.001) -> EKFSLAM:
    """A filter with an uncertain pose and one landmark 3 m away seen once, then a prediction
    that adds position noise (Σ invertible)."""
    f = EKFSLAM([0.2, -0.1, 0.3], np.diag([0.04, 0.03, heading_variance]), config)
    f.update(7, (3.0, 0.4), Q)
    f.predict([0.0, 0.0, 0.0], np.diag([0.02, 0.02, 0.0]))
    return f


def _map_cost(mu0, Sigma0, z, delta):
    """The MAP cost of one observation at x = x̂ + δ: ½|z - h(x)|²_Q⁻¹ + ½ δᵀ Σ⁻¹ δ."""
    x = mu0 + delta
    r = z - observation(x[:3], x[3:5])
    r[1] = wrap_angle(float(r[1]))
    return 0.5 * r @ np.linalg.solve(Q, r) + 0.5 * delta @ np.linalg.solve(Sigma0, delta)


@pytest.mark.parametrize(("iterations", "stationary"), [(1, False), (50, True)])
def test_the_converged_standard_update_is_a_stationary_point_of_the_map_cost(
    iterations, stationary
):
    f = _one_landmark(FilterConfig(iterations=iterations, gate=None))
    mu0, Sigma0 = f.mu.copy(), f.Sigma.copy()
    z = np.array([2.6, 0.55])  # 0.4 m and 0.15 rad off the prediction: strongly nonlinear
    f.update(7, z, Q)
    delta = f.mu - mu0
    grad = np.empty(5)
    for k in range(5):  # central differences of the cost
        e = np.zeros(5)
        e[k] = 1e-6
        grad[k] = (
            _map_cost(mu0, Sigma0, z, delta + e) - _map_cost(mu0, Sigma0, z, delta - e)
        ) / 2e-6
    scale = np.abs(np.linalg.solve(Sigma0, delta)).max()  # the size of either term's gradient
    if stationary:
        assert np.abs(grad).max() < 1e-5 * scale  # measured 1.3e-7 against a scale of 34
    else:  # one linearisation stops short of the minimum: measured 16.8 against 37
        assert np.abs(grad).max() > 1e-2 * scale


def test_iterating_lowers_the_map_cost_and_keeps_the_first_innovation_in_the_history():
    costs, nis, ran = [], [], []
    z = np.array([2.6, 0.55])
    for iterations in (1, 2, 3, 10):
        f = _one_landmark(FilterConfig(iterations=iterations, gate=None))
        mu0, Sigma0 = f.mu.copy(), f.Sigma.copy()
        f.update(7, z, Q)
        costs.append(_map_cost(mu0, Sigma0, z, f.mu - mu0))
        nis.append(f.history().obs_nis[-1])
        ran.append(f._linearisations)
    assert costs[0] > costs[1] > costs[2] > costs[3]  # measured 6.034, 5.788, 5.787, 5.787
    assert costs[0] - costs[3] > 0.2
    assert ran[1:] == [2, 3, 8]  # converged after 8 linearisations
    assert nis == pytest.approx([nis[0]] * 4, rel=1e-12)  # the χ² test of the prediction


def test_a_step_that_would_raise_the_map_cost_is_not_taken():
    # the heading uncertain (σθ 0.14 rad) and the landmark just placed from it: plain
    # Gauss-Newton overshoots here and its cost climbs (22.6 -> 27.2 -> 86.4, measured with the
    # undamped iteration); the iterated update then keeps the plain EKF's step
    z = np.array([2.6, 0.55])
    costs = []
    for iterations in (1, 2, 10):
        f = EKFSLAM(
            [0.2, -0.1, 0.3],
            np.diag([0.04, 0.03, 0.02]),
            FilterConfig(iterations=iterations, gate=None),
        )
        f.update(7, (3.0, 0.4), Q)
        mu0, Sigma0 = f.mu.copy(), f.Sigma.copy()
        f.update(7, z, Q)
        costs.append(_map_cost(mu0, Sigma0, z, f.mu - mu0))
    assert costs == pytest.approx([costs[0]] * 3, rel=1e-12)


def test_the_gate_decides_on_the_first_linearisation():
    z = np.array([1.0, 1.5])  # far outside the gate
    plain = _one_landmark(FilterConfig())
    iterated = _one_landmark(FilterConfig(iterations=5))
    assert plain.update(7, z, Q) == iterated.update(7, z, Q)
    assert plain.counts.rejected == iterated.counts.rejected == 1
    np.testing.assert_array_equal(plain.mu, iterated.mu)


@pytest.mark.parametrize("linearization", ["standard", "invariant"])
def test_the_iterated_filter_replays_a_seed_run_as_the_literal_reference(linearization):
    run = read_run(seed_runs_dir() / "octagon-2laps")
    s = pipeline.schedule(run, default_noise(run))
    upto, us, dts, ends, M, R_fixed = s.upto, s.u, s.dt, s.t, s.M, s.R
    ids, times, zs, Q_run = s.ids, s.times, s.z, s.Q
    config = FilterConfig(linearization=linearization, iterations=3)
    start = run.meta.nominal_start
    fast, slow = EKFSLAM(start, None, config), LiteralEKFSLAM(start, None, config)
    plain = EKFSLAM(start, None, FilterConfig(linearization=linearization))

    done = 0
    for i, p in enumerate(upto):
        if p > done:
            fast.predict_many(us[done:p], dts[done:p], ends[done:p], M, R_fixed)
            plain.predict_many(us[done:p], dts[done:p], ends[done:p], M, R_fixed)
            for k in range(done, p):
                slow.predict(us[k], R_fixed if M is None else motion_noise(slow.mu, M * dts[k]))
            done = p
        assert fast.update(ids[i], zs[i], Q_run, times[i]) == slow.update(ids[i], zs[i], Q_run)
        plain.update(ids[i], zs[i], Q_run, times[i])
    assert fast.counts.accepted > 500 and fast.n_landmarks == 8
    np.testing.assert_allclose(fast.mu, slow.mu, rtol=0, atol=1e-9)
    Sigma = slow.cartesian_Sigma if linearization == "invariant" else slow.Sigma
    np.testing.assert_allclose(fast.Sigma, Sigma, rtol=0, atol=1e-9)
    assert np.abs(fast.mu - plain.mu).max() > 1e-6  # the iterations did move it


def test_iterations_are_checked():
    with pytest.raises(ConfigError, match="iterations must be a whole number 1 to 100"):
        FilterConfig(iterations=0)
    with pytest.raises(ConfigError, match="iterations"):
        FilterConfig(iterations=2.0)
    with pytest.raises(ConfigError, match="iterations"):
        FilterConfig(iterations=True)
    with pytest.raises(ConfigError, match="FEJ"):
        FilterConfig(linearization="fej", iterations=2)
    assert FilterConfig().iterations == 1
