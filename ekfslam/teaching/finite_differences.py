"""Jacobians by finite differences: check a model's hand-written Jacobians before the filter
trusts them (the Robotics Toolbox ships its ``numjac`` the same way, with the library).

`central` is ∂f/∂x at a point by central differences; `jacobian_errors` compares every Jacobian
of a `MotionModel` or a `SensorModel` (`ekfslam.core.models`) with it at one point and returns
the largest difference of each, so that a new sensor is checked in one line::

    from ekfslam.teaching.finite_differences import jacobian_errors
    errors = jacobian_errors(my_sensor, pose=(0.1, -0.2, 0.3), other=(2.0, 1.0))
    assert max(errors.values()) < 1e-6, errors

An angle among the outputs (a bearing) is differenced wrapped to [-π, π), so that a point near
the ±π seam does not read as a jump of 2π.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.checks import array
from ekfslam.core.models import MotionModel, SensorModel
from ekfslam.errors import WrongTypeError
from ekfslam.geometry import wrap_angle

Array = NDArray[np.float64]

#: The step of `central` (the truncation error is O(eps²), the rounding error O(1e-16 / eps)).
EPS = 1e-6


def central(
    fn: Callable[[Array], ArrayLike], x: ArrayLike, eps: float = EPS, angles: Sequence[int] = ()
) -> Array:
    """∂fn/∂x at x by central differences: (m, k) for fn's m outputs and x's k entries.

    Parameters
    ----------
    fn : a function of a vector (k,) that returns a vector (m,).
    x : (k,) the point.
    eps : the step in each entry of x.
    angles : indices of fn's outputs that are angles, differenced wrapped to [-π, π).
    """
    x = array(x, "central: x", (None,), "a point (a vector of numbers)")
    cols = []
    for k in range(len(x)):
        e = np.zeros(len(x))
        e[k] = eps
        diff = np.asarray(fn(x + e), dtype=float) - np.asarray(fn(x - e), dtype=float)
        for i in angles:
            diff[i] = wrap_angle(float(diff[i]))
        cols.append(diff / (2 * eps))
    return np.column_stack(cols)


def jacobian_errors(
    model: MotionModel | SensorModel,
    pose: ArrayLike,
    other: ArrayLike,
    eps: float = EPS,
    angles: Sequence[int] = (1,),
    dt: float = 0.0,
) -> dict[str, float]:
    """The largest |hand-written - finite-difference| of each of the model's Jacobians at one
    point: {"F_x": ..., "F_v": ...} for a motion model at (pose, u = other, dt); {"H_r", "H_l",
    "G_r", "G_z"} for a sensor at (pose, landmark = other) for h, and at (pose, z = h(pose,
    landmark)) for g (only "H_r", "H_l" for a sensor without g, which places a landmark from two
    sightings). angles : which of the sensor's outputs are angles (the bearing, by default);
    the pose's heading is always one. dt : s, the motion model's step."""
    pose = array(pose, "jacobian_errors: pose", (3,), "a pose (x, y, theta)")
    other = array(other, "jacobian_errors: other", (None,), "a control u or a landmark")
    if isinstance(model, MotionModel):
        return {
            "F_x": _largest(
                model.F_x(pose, other, dt),
                central(lambda p: model.f(p, other, dt), pose, eps, (2,)),
            ),
            "F_v": _largest(
                model.F_v(pose, other, dt),
                central(lambda v: model.f(pose, v, dt), other, eps, (2,)),
            ),
        }
    if not isinstance(model, SensorModel):
        raise WrongTypeError(
            "jacobian_errors: model must be a MotionModel or a SensorModel of "
            f"ekfslam.core.models, got {type(model).__name__}"
        )
    H_r, H_l = model.H(pose, other)
    errors = {
        "H_r": _largest(H_r, central(lambda p: model.h(p, other), pose, eps, angles)),
        "H_l": _largest(H_l, central(lambda m: model.h(pose, m), other, eps, angles)),
    }
    if model.g is None:
        return errors
    z = np.asarray(model.h(pose, other), dtype=float)
    G_r, G_z = model.G(pose, z)
    errors["G_r"] = _largest(G_r, central(lambda p: model.g(p, z), pose, eps))
    errors["G_z"] = _largest(G_z, central(lambda v: model.g(pose, v), z, eps))
    return errors


def _largest(analytic: ArrayLike, numeric: Array) -> float:
    return float(np.abs(np.asarray(analytic, dtype=float) - numeric).max())
