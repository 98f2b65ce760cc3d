"""Tests of ekfslam.core.steps, the filter's steps on plain arrays (eqs. 13-16): by hand, and the
compiled steps and the literal F_x,j reference held to them on random states."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam import EKFSLAM, FilterConfig
from ekfslam.core.filter.backend import steps_for
from ekfslam.core.filter.history import OBS_COLUMNS, OBS_NIS, OBS_ROW, Outcome
from ekfslam.core.filter.steps import Linearization
from ekfslam.core.models import ODOMETRY, RANGE_BEARING, observation
from ekfslam.core.steps import update_steps
from ekfslam.geometry import wrap_angle
from ekfslam.teaching.reference import LiteralEKFSLAM


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


def random_state(seed: int):
    """1-6 landmarks with a random SPD Σ, a slot j and a plausible observation z of it."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 7))
    d = 3 + 2 * n
    mu = rng.normal(0.0, 1.0, d)
    mu[2] = wrap_angle(float(mu[2]))
    A = rng.normal(0.0, 0.1, (d, d))
    Sigma = A @ A.T + 1e-4 * np.eye(d)
    j = int(rng.integers(n))
    l = 3 + 2 * j
    while np.hypot(*(mu[l : l + 2] - mu[:2])) < 0.2:  # a landmark well off the robot
        mu[l : l + 2] = rng.normal(0.0, 1.0, 2)
    Q = np.diag(rng.uniform(0.01, 0.1, 2) ** 2)
    z = observation(mu[:3], mu[l : l + 2]) + rng.normal(0.0, 0.05, 2)
    return mu, Sigma, j, z, Q


SEEDS = range(25)


@pytest.mark.parametrize("invariant", [False, True])
@pytest.mark.parametrize("seed", SEEDS)
def test_the_compiled_correction_is_the_block_form(seed: int, invariant: bool) -> None:
    mu, Sigma, j, z, Q = random_state(seed)
    steps = update_steps(mu, Sigma, j, z, Q, invariant=invariant)
    d, l, capacity = len(mu), 3 + 2 * j, len(mu) + 4  # storage larger than the state, as in EKFSLAM
    lin = Linearization.INVARIANT if invariant else Linearization.STANDARD
    storage = (np.zeros(capacity), np.zeros((capacity, capacity)), np.zeros(capacity), np.zeros(2))
    storage[0][:d], storage[1][:d, :d] = mu, Sigma
    obs = np.full(len(OBS_ROW), math.nan)
    point = np.concatenate([mu[:3], mu[l : l + 2]])
    compiled = steps_for(ODOMETRY, RANGE_BEARING, "numba")
    outcome = compiled.correct((*storage, int(lin)), d, l, (z, Q, math.inf, point), obs)
    assert outcome == Outcome.ACCEPTED
    np.testing.assert_array_equal(storage[1], storage[1].T)  # both halves, exactly symmetric
    np.testing.assert_allclose(obs[OBS_COLUMNS.z_hat], steps.z_hat, rtol=0, atol=1e-9)
    np.testing.assert_allclose(obs[OBS_COLUMNS.innovation], steps.nu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(obs[OBS_COLUMNS.S], steps.S.ravel(), rtol=0, atol=1e-9)
    assert obs[OBS_NIS] == pytest.approx(steps.nis, rel=0, abs=1e-9)
    np.testing.assert_allclose(storage[0][:d], steps.mu_post, rtol=0, atol=1e-9)
    np.testing.assert_allclose(storage[1][:d, :d], steps.Sigma_joseph, rtol=0, atol=1e-9)


@pytest.mark.parametrize("linearization", ["standard", "invariant"])
@pytest.mark.parametrize("seed", SEEDS)
def test_the_literal_reference_correction_is_the_block_form(seed: int, linearization) -> None:
    mu, Sigma, j, z, Q = random_state(seed)
    steps = update_steps(mu, Sigma, j, z, Q, invariant=linearization == "invariant")
    n = (len(mu) - 3) // 2
    literal = LiteralEKFSLAM(mu[:3], config=FilterConfig(gate=None, linearization=linearization))
    # the reference has no constructor from a state: give it one landmark per slot, seen once
    literal.mu, literal.Sigma = mu.copy(), Sigma.copy()
    literal.slot = {10 + k: k for k in range(n)}
    literal._sightings = [1] * n
    literal._first = [mu[3 + 2 * k : 5 + 2 * k].copy() for k in range(n)]
    literal._rejected = [[] for _ in range(n)]
    assert literal.update(10 + j, z, Q) == Outcome.ACCEPTED
    np.testing.assert_allclose(literal.mu, steps.mu_post, rtol=0, atol=1e-9)
    np.testing.assert_allclose(literal.Sigma, steps.Sigma_joseph, rtol=0, atol=1e-9)
    # the seed's printed (I - KH) Σ is Joseph's form for the optimal gain
    np.testing.assert_allclose(steps.Sigma_seed, steps.Sigma_joseph, rtol=0, atol=1e-9)


def test_update_steps_refuses_a_slot_outside_the_state() -> None:
    with pytest.raises(ValueError, match="slot 1"):
        update_steps(np.zeros(5), np.eye(5), 1, [1.0, 0.0], np.eye(2))


@pytest.mark.parametrize("backend", ["python", "numba"])
@pytest.mark.parametrize("linearization", ["standard", "fej", "invariant"])
def test_the_steps_keep_the_upper_triangle_so_the_pose_rows_are_whole(backend, linearization):
    """Σ[r, :d] is the pose's contiguous rows of the storage, current after every step (what
    makes the prediction's Σ[r, m] = G Σ[r, m] and the correction's H Σ read memory in order);
    the lower triangle is filled in only when Σ is handed out."""
    f = EKFSLAM(
        [0.1, -0.2, 0.3],
        np.diag([1e-3, 2e-3, 1e-4]),
        FilterConfig(linearization=linearization, gate=None, backend=backend),
    )
    Q, R = np.diag([0.05**2, 0.03**2]), np.diag([1e-4, 2e-4, 3e-5])
    rng = np.random.default_rng(5)
    for k in range(40):
        f.predict([0.05, 0.01, 0.02], R)
        f.update(k % 7, (rng.uniform(1, 3), rng.uniform(-3, 3)), Q)
    f.settle()
    d, stored = 3 + 2 * f.n_landmarks, f._storage.Sigma.copy()  # before Sigma mirrors it
    whole = f.invariant_covariance if linearization == "invariant" else f.Sigma
    upper = np.triu_indices(d)
    np.testing.assert_allclose(stored[:3, 3:d], whole[:3, 3:d], rtol=0, atol=1e-15)  # Σ[r, m]
    np.testing.assert_allclose(stored[:d, :d][upper], whole[upper], rtol=0, atol=1e-15)
