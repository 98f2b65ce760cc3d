"""The invariant EKF's sympy Jacobians against finite differences of the exact maps, and against
the forms the filter uses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam.core.invariant import INVARIANT_NEW_LANDMARK_POSE, noise_map, retract
from ekfslam.core.models import (
    inverse_observation,
    inverse_observation_jacobians,
    motion,
    observation,
    observation_jacobians,
)
from ekfslam.teaching.finite_differences import central
from ekfslam.teaching.invariant import invariant_numeric

EPS = 1e-6


def log_error(true: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """ξ with true = exp(ξ) estimate, exactly (pose and one landmark)."""
    a = true[2] - estimate[2]
    c, s = math.cos(a), math.sin(a)
    V = np.array([[math.sin(a), -(1 - c)], [1 - c, math.sin(a)]]) / a if a else np.eye(2)
    R = np.array([[c, -s], [s, c]])
    p = np.linalg.solve(V, true[:2] - R @ estimate[:2])
    m = np.linalg.solve(V, true[3:5] - R @ estimate[3:5])
    return np.array([p[0], p[1], a, m[0], m[1]])


def moved(state: np.ndarray, u: np.ndarray, noise=(0.0, 0.0, 0.0)) -> np.ndarray:
    return np.concatenate([motion(state[:3], u) + np.asarray(noise), state[3:5]])


def points(seed: int):
    rng = np.random.default_rng(seed)
    state = np.array([*rng.uniform(-3, 3, 2), rng.uniform(-3, 3), *rng.uniform(-3, 3, 2)])
    u = np.array([rng.uniform(0, 0.3), rng.uniform(-0.1, 0.1), rng.uniform(-0.5, 0.5)])
    z = np.array([rng.uniform(0.5, 4.0), rng.uniform(-3, 3)])
    return state, u, z


@pytest.mark.parametrize("seed", range(5))
def test_the_derived_jacobians_are_the_exact_maps_derivatives(seed: int) -> None:
    state, u, z = points(seed)
    d = invariant_numeric()
    after = moved(state, u)
    # propagation: ξ' = log(f(exp(ξ) X̂) f(X̂)⁻¹) has the identity for Jacobian
    F = central(lambda xi: log_error(moved(retract(state, xi), u), after), np.zeros(5), EPS)
    np.testing.assert_allclose(d.F(state[:3], state[3:], u), F, rtol=0, atol=1e-7)
    np.testing.assert_allclose(F, np.eye(5), rtol=0, atol=1e-7)
    # a Cartesian pose noise after the step
    N = central(lambda n: log_error(moved(state, u, n), after), np.zeros(3), EPS)
    np.testing.assert_allclose(d.noise(state[:3], state[3:], u), N, rtol=0, atol=1e-7)
    # observation: ẑ(exp(ξ) X̂), the bearing wrapped near its value
    z0 = observation(state[:3], state[3:])

    def h(xi):
        x = retract(state, xi)
        dz = observation(x[:3], x[3:]) - z0
        dz[1] = (dz[1] + math.pi) % (2 * math.pi) - math.pi
        return dz

    np.testing.assert_allclose(d.H(state[:3], state[3:]), central(h, np.zeros(5), EPS), atol=1e-7)
    # a new landmark: ξ_m of m(exp(ξ) pose, z + δz)
    m0 = inverse_observation(state[:3], z)

    def xi_m(v):
        pose = retract(np.concatenate([state[:3], [0.0, 0.0]]), [*v[:3], 0.0, 0.0])[:3]
        m = inverse_observation(pose, z + v[3:])
        return log_error(np.concatenate([pose, m]), np.concatenate([state[:3], m0]))[3:]

    G = central(xi_m, np.zeros(5), EPS)
    np.testing.assert_allclose(d.G_pose(state[:3], z), G[:, :3], rtol=0, atol=1e-7)
    np.testing.assert_allclose(d.G_z(state[:3], z), G[:, 3:], rtol=0, atol=1e-7)


@pytest.mark.parametrize("seed", range(5))
def test_the_filter_uses_the_derived_jacobians(seed: int) -> None:
    state, u, z = points(seed)
    d = invariant_numeric()
    H_r, H_l = observation_jacobians(state[:3], state[3:])
    H = np.hstack([H_r, H_l])
    H[:, 2] = 0.0  # kernels.correct and steps.update_steps(invariant=True)
    np.testing.assert_allclose(d.H(state[:3], state[3:]), H, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        d.noise(state[:3], state[3:], u), noise_map(moved(state, u)), rtol=0, atol=1e-12
    )
    np.testing.assert_array_equal(d.G_pose(state[:3], z), INVARIANT_NEW_LANDMARK_POSE)
    _, G_z = inverse_observation_jacobians(state[:3], z)
    np.testing.assert_allclose(d.G_z(state[:3], z), G_z, rtol=0, atol=1e-12)
