"""The robot-to-robot model of `ekfslam.core.models`: against sympy, finite differences and
plain geometry, on generated pairs of poses (every quadrant, headings next to ±π)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given
from hypothesis import strategies as st

from ekfslam.core import models
from ekfslam.geometry import invert, transform_points, wrap_angle
from ekfslam.teaching.derivations import robot_observation_model
from ekfslam.teaching.symbols import POSE, TARGET

H = 1e-6
coordinate = st.floats(-5, 5)
heading = st.one_of(
    st.floats(-math.pi, math.pi, exclude_max=True),
    st.sampled_from([math.pi - 1e-9, -math.pi, -math.pi + 1e-9]),
)
poses = st.tuples(coordinate, coordinate, heading).map(np.array)
apart = st.tuples(poses, poses).filter(lambda p: np.hypot(*(p[1][:2] - p[0][:2])) > 0.05)


@pytest.fixture(scope="module")
def symbolic():
    model = robot_observation_model()
    args = [*POSE, *TARGET]
    return tuple(
        sp.lambdify(args, e, "numpy")
        for e in (model.value, model.jacobian_pose, model.jacobian_input)
    )


def _numeric_jacobian(f, a, b, which):
    J = np.zeros((2, 3))
    for k in range(3):
        step = np.zeros(3)
        step[k] = H
        if which == 0:
            plus, minus = f(a + step, b), f(a - step, b)
        else:
            plus, minus = f(a, b + step), f(a, b - step)
        diff = plus - minus
        diff[1] = wrap_angle(diff[1])
        J[:, k] = diff / (2 * H)
    return J


@given(apart)
def test_the_sighting_is_the_target_in_the_observers_frame(pair):
    a, b = pair
    z = models.robot_observation(a, b)
    local = transform_points(invert(a), b[:2].reshape(1, 2))[0]
    assert math.isclose(z[0], math.hypot(*local), rel_tol=1e-12, abs_tol=1e-12)
    assert abs(wrap_angle(z[1] - math.atan2(local[1], local[0]))) < 1e-9
    assert -math.pi <= z[1] < math.pi


@given(apart)
def test_jacobians_are_the_finite_differences(pair):
    a, b = pair
    H_a, H_b = models.robot_observation_jacobians(a, b)
    f = models.robot_observation
    scale = 1 + 1 / np.hypot(*(b[:2] - a[:2])) ** 2
    assert np.allclose(H_a, _numeric_jacobian(f, a, b, 0), atol=1e-6 * scale)
    assert np.allclose(H_b, _numeric_jacobian(f, a, b, 1), atol=1e-6 * scale)
    assert np.all(H_b[:, 2] == 0.0)  # the target's heading does not move its centre


@given(apart)
def test_the_model_is_the_sympy_derivation(symbolic, pair):
    a, b = pair
    value, J_a, J_b = (np.array(f(*a, *b), dtype=float) for f in symbolic)
    z = models.robot_observation(a, b)
    assert math.isclose(z[0], value[0, 0], rel_tol=1e-12)
    assert abs(wrap_angle(z[1] - value[1, 0])) < 1e-12
    H_a, H_b = models.robot_observation_jacobians(a, b)
    assert np.allclose(H_a, J_a, rtol=1e-10, atol=1e-12)
    assert np.allclose(H_b, J_b, rtol=1e-10, atol=1e-12)


def test_the_record_and_robots_on_one_another():
    record = models.ROBOT_RANGE_BEARING
    assert record.h is models.robot_observation and record.H is models.robot_observation_jacobians
    with pytest.raises(models.DegenerateGeometry):
        models.robot_observation(np.array([1.0, 2.0, 0.3]), np.array([1.0, 2.0, -1.0]))
