"""ekfslam.core.kinematics: mecanum wheel speeds <-> body twist, signs, and noise propagation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam.core import kinematics
from ekfslam.core.kinematics import (
    MecanumGeometry,
    twist_to_wheels,
    wheel_noise_to_twist_covariance,
    wheels_to_twist,
)

GEOMETRY = MecanumGeometry(wheel_radius=0.03, lx=0.068, ly=0.054)
# Front wheels against rear wheels: by the documented equations, the one combination that moves
# nothing (it is orthogonal to the vx, vy and ωz rows).
NULL = np.array([1.0, 1.0, -1.0, -1.0]) / 2.0


def test_twist_wheels_twist_is_exact():
    rng = np.random.default_rng(1)
    twists = rng.uniform(-1, 1, (500, 3))
    np.testing.assert_allclose(
        wheels_to_twist(twist_to_wheels(twists, GEOMETRY), GEOMETRY), twists, rtol=0, atol=1e-12
    )
    one = np.array([0.2, -0.1, 0.7])
    back = wheels_to_twist(twist_to_wheels(one, GEOMETRY), GEOMETRY)
    assert back.shape == (3,)
    np.testing.assert_allclose(back, one, rtol=0, atol=1e-12)


def test_null_combination_moves_nothing():
    np.testing.assert_allclose(wheels_to_twist(NULL, GEOMETRY), np.zeros(3), atol=1e-15)


def test_wheels_twist_wheels_removes_the_null_component():
    rng = np.random.default_rng(2)
    wheels = rng.uniform(-10, 10, (500, 4))
    projected = wheels - np.outer(wheels @ NULL, NULL)
    again = twist_to_wheels(wheels_to_twist(wheels, GEOMETRY), GEOMETRY)
    np.testing.assert_allclose(again, projected, rtol=0, atol=1e-10)
    assert np.abs(again @ NULL).max() < 1e-10
    # and a wheel vector that was already free of it comes back unchanged
    np.testing.assert_allclose(
        twist_to_wheels(wheels_to_twist(projected, GEOMETRY), GEOMETRY), projected, atol=1e-10
    )


def test_documented_null_combination_moves_nothing():
    """Regression: the docstring once named (1, -1, -1, 1), which is pure sideways motion."""
    assert "(w1 + w2 - w3 - w4)" in kinematics.__doc__
    twist = wheels_to_twist([1.0, 1.0, -1.0, -1.0], GEOMETRY)
    np.testing.assert_allclose(twist, np.zeros(3), atol=1e-12)


def test_pure_forward_wheel_speeds_give_pure_vx():
    omega = 5.0  # rad/s
    vx, vy, wz = wheels_to_twist([omega] * 4, GEOMETRY)
    assert vx == pytest.approx(GEOMETRY.wheel_radius * omega, rel=1e-15)
    assert vy == 0.0 and wz == 0.0


def test_sign_convention():
    r, k = GEOMETRY.wheel_radius, GEOMETRY.lx + GEOMETRY.ly
    # left wheels back, right wheels forward: counter-clockwise spin on the spot
    vx, vy, wz = wheels_to_twist([-1.0, 1.0, -1.0, 1.0], GEOMETRY)
    assert vx == pytest.approx(0.0, abs=1e-15) and vy == pytest.approx(0.0, abs=1e-15)
    assert wz == pytest.approx(r / k) and wz > 0
    # FL and RR back, FR and RL forward: strafe to the left (+y)
    vx, vy, wz = wheels_to_twist([-1.0, 1.0, 1.0, -1.0], GEOMETRY)
    assert vx == pytest.approx(0.0, abs=1e-15) and wz == pytest.approx(0.0, abs=1e-15)
    assert vy == pytest.approx(r) and vy > 0
    # and back: a pure left strafe asks exactly that of the wheels
    np.testing.assert_allclose(twist_to_wheels([0.0, r, 0.0], GEOMETRY), [-1, 1, 1, -1])


def test_matrices_are_inverse_and_pseudo_inverse():
    J = GEOMETRY.wheels_to_twist_matrix
    M = GEOMETRY.twist_to_wheels_matrix
    assert J.shape == (3, 4) and M.shape == (4, 3)
    np.testing.assert_allclose(J @ M, np.eye(3), rtol=0, atol=1e-12)
    np.testing.assert_allclose(M, np.linalg.pinv(J), rtol=0, atol=1e-9)


def test_wheel_noise_to_twist_covariance_matches_monte_carlo():
    sigma = np.array([0.1, 0.2, 0.3, 0.4])  # rad/s, different per wheel so the twist correlates
    C = wheel_noise_to_twist_covariance(sigma, GEOMETRY)
    rng = np.random.default_rng(12345)
    samples = wheels_to_twist(rng.normal(size=(200_000, 4)) * sigma, GEOMETRY)
    C_mc = np.cov(samples, rowvar=False)
    scale = np.sqrt(np.outer(np.diag(C), np.diag(C)))
    assert np.all(np.abs(C_mc - C) <= 0.02 * scale), (C, C_mc)
    assert abs(C[0, 1]) > 0.1 * scale[0, 1]  # the off-diagonals are not trivially zero


def test_wheel_noise_scalar_sigma_hand_computed():
    s, r, k = 0.5, GEOMETRY.wheel_radius, GEOMETRY.lx + GEOMETRY.ly
    C = wheel_noise_to_twist_covariance(s, GEOMETRY)
    # each row of J has four entries ±r/4 (±r/(4k) for ωz): variance 4 (r/4)² s² = r² s² / 4
    expected = np.diag([r**2 * s**2 / 4, r**2 * s**2 / 4, r**2 * s**2 / (4 * k**2)])
    np.testing.assert_allclose(C, expected, rtol=1e-12, atol=1e-18)


@pytest.mark.parametrize("field", ["wheel_radius", "lx", "ly"])
@pytest.mark.parametrize("value", [0.0, -0.01, math.nan, math.inf])
def test_geometry_rejects_non_positive_sizes(field, value):
    with pytest.raises(ValueError, match=field):
        MecanumGeometry(**{field: value})


def test_wrong_shapes_are_rejected():
    with pytest.raises(ValueError, match=r"wheels_to_twist: wheels .*: 4 numbers, got 3"):
        wheels_to_twist([1.0, 2.0, 3.0], GEOMETRY)
    with pytest.raises(ValueError, match=r"twist_to_wheels: twist .*: 3 numbers, got 4"):
        twist_to_wheels([1.0, 2.0, 3.0, 4.0], GEOMETRY)


def test_nan_wheel_speeds_and_a_missing_geometry_are_refused_not_returned_as_nan():
    with pytest.raises(ValueError, match=r"wheels_to_twist: wheels must be finite .*nan"):
        wheels_to_twist([[1.0, 2.0, 3.0, 4.0], [math.nan, 0.0, 0.0, 0.0]], GEOMETRY)
    with pytest.raises(TypeError, match="wheels_to_twist: geometry must be a MecanumGeometry"):
        wheels_to_twist([1.0, 2.0, 3.0, 4.0], None)
    with pytest.raises(TypeError, match="twist_to_wheels: twist must be a body twist"):
        twist_to_wheels("0.1, 0, 0", GEOMETRY)
