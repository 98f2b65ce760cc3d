"""The finite-difference checker shipped in the package (`ekfslam.teaching.finite_differences`):
it agrees with every hand-written Jacobian of the seed's models, near the bearing's ±π seam too,
and it catches a wrong one."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ekfslam.core.models import ODOMETRY, RANGE_BEARING
from ekfslam.errors import WrongTypeError
from ekfslam.teaching.finite_differences import central, jacobian_errors

coordinate = st.floats(-5.0, 5.0)
heading = st.floats(-np.pi, np.pi)


@settings(max_examples=60, deadline=None)
@given(x=coordinate, y=coordinate, theta=heading, a=coordinate, b=coordinate, c=heading)
def test_the_seed_models_jacobians_are_their_finite_differences(x, y, theta, a, b, c) -> None:
    pose = (x, y, theta)
    assert max(jacobian_errors(ODOMETRY, pose, (a, b, 0.3 * c)).values()) < 1e-6
    if (a - x) ** 2 + (b - y) ** 2 > 0.25:  # a landmark half a metre off the robot or more
        assert max(jacobian_errors(RANGE_BEARING, pose, (a, b)).values()) < 1e-5


def test_a_bearing_at_the_seam_is_differenced_wrapped() -> None:
    pose, behind = (0.0, 0.0, 0.0), (-2.0, 1e-9)  # bearing ≈ π: h jumps to -π a step away
    assert jacobian_errors(RANGE_BEARING, pose, behind)["H_l"] < 1e-6
    raw = central(lambda m: RANGE_BEARING.h(pose, m), behind, angles=())
    assert np.abs(raw).max() > 1e5  # without the wrap: a jump of 2π over 2e-6


def test_a_wrong_jacobian_is_caught() -> None:
    def H(pose, landmark):
        H_r, H_l = RANGE_BEARING.H(pose, landmark)
        return H_r, -H_l  # a sign error

    wrong = dataclasses.replace(RANGE_BEARING, H=H, name="wrong")
    errors = jacobian_errors(wrong, (0.0, 0.0, 0.2), (2.0, 1.0))
    assert errors["H_l"] > 0.1 and errors["H_r"] < 1e-6


def test_not_a_model_is_one_line() -> None:
    with pytest.raises(WrongTypeError, match="must be a MotionModel or a SensorModel"):
        jacobian_errors("odometry", (0.0, 0.0, 0.0), (1.0, 1.0))
