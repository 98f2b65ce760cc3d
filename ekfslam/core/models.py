"""The motion and observation models of the seed report, with their Jacobians.

Pose p = (x, y, θ) in m, m, rad. Control increment u = (Δux, Δuy, Δθ) in the body frame (eq. 4).
Observation z = (r, φ): range in m and bearing in rad, measured from the robot's heading (eq. 10).
Landmark m = (mx, my) in m.

These are the numeric forms used by the filter. `ekfslam.teaching.derivations` derives the same
expressions symbolically with sympy, and the tests check that the two agree.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.geometry import wrap_angle

Array = NDArray[np.float64]

#: Squared range (m^2) below which a landmark is "at the robot" and its bearing is undefined.
MIN_RANGE_SQUARED = 1e-12


class DegenerateGeometry(ValueError):
    """An observation that cannot be linearised: the landmark sits on the robot."""


def motion(pose: ArrayLike, u: ArrayLike) -> Array:
    """Predicted pose after the body-frame increment u, eqs. (5)-(6).

    Parameters
    ----------
    pose : array (3,)   (x, y, θ) at t-1.
    u : array (3,)      (Δux, Δuy, Δθ), eq. (4).

    Returns
    -------
    array (3,)  (x, y, θ) at t|t-1, θ wrapped to [-π, π).
    """
    x, y, th = pose[0], pose[1], pose[2]
    dux, duy, dth = u[0], u[1], u[2]
    c, s = math.cos(th), math.sin(th)
    return np.array([x + dux * c - duy * s, y + dux * s + duy * c, wrap_angle(float(th + dth))])


def motion_jacobian(pose: ArrayLike, u: ArrayLike) -> Array:
    """G: the 3x3 Jacobian of eq. (6) with respect to the pose (the block inside eq. 7)."""
    th = pose[2]
    dux, duy = u[0], u[1]
    c, s = math.cos(th), math.sin(th)
    return np.array(
        [
            [1.0, 0.0, -dux * s - duy * c],
            [0.0, 1.0, dux * c - duy * s],
            [0.0, 0.0, 1.0],
        ]
    )


def motion_control_jacobian(pose: ArrayLike) -> Array:
    """V: the 3x3 Jacobian of eq. (6) with respect to the control u (the rotation of eq. 5).

    A control-noise covariance M (in u-space) becomes the state-space motion noise R = V M Vᵀ.
    """
    th = pose[2]
    c, s = math.cos(th), math.sin(th)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def motion_noise(pose: ArrayLike, M: ArrayLike) -> Array:
    """R = V M Vᵀ (3x3): control-increment covariance M (3x3, u-space) mapped into the state."""
    V = motion_control_jacobian(pose)
    R = V @ np.asarray(M, dtype=float) @ V.T
    return 0.5 * (R + R.T)


def _offset(pose: ArrayLike, landmark: ArrayLike) -> tuple[float, float, float]:
    """δ = landmark - robot position and q = δᵀδ of eq. (13), refusing a landmark on the robot."""
    dx = landmark[0] - pose[0]
    dy = landmark[1] - pose[1]
    q = dx * dx + dy * dy
    if not q > MIN_RANGE_SQUARED:
        raise DegenerateGeometry(
            f"landmark at ({landmark[0]:.6g}, {landmark[1]:.6g}) sits on the robot"
        )
    return dx, dy, q


def observation(pose: ArrayLike, landmark: ArrayLike) -> Array:
    """ẑ = (r, φ): predicted range and bearing of a landmark, eq. (13), with atan2.

    The seed writes arctan(δy/δx) - θ, which is wrong by π whenever δx < 0; atan2 is right in all
    four quadrants. The bearing is wrapped to [-π, π).

    Raises
    ------
    DegenerateGeometry
        When the landmark is within 1e-6 m of the robot (no bearing is defined there).
    """
    dx, dy, q = _offset(pose, landmark)
    return np.array([math.sqrt(q), wrap_angle(math.atan2(dy, dx) - float(pose[2]))])


def observation_jacobians(pose: ArrayLike, landmark: ArrayLike) -> tuple[Array, Array]:
    """The two non-zero blocks of H, eq. (14): ∂ẑ/∂pose (2x3) and ∂ẑ/∂landmark (2x2).

    Eq. (14) writes them side by side as a 2x5 matrix times the lift F_x,j; the efficient filter
    uses the blocks directly.
    """
    dx, dy, q = _offset(pose, landmark)
    r = math.sqrt(q)
    a, b = dx / r, dy / r
    c, d = dy / q, dx / q
    H_pose = np.array([[-a, -b, 0.0], [c, -d, -1.0]])
    H_landmark = np.array([[a, b], [-c, d]])
    return H_pose, H_landmark


def inverse_observation(pose: ArrayLike, z: ArrayLike) -> Array:
    """Landmark position from the pose and one observation, eq. (12)."""
    r, phi = z[0], z[1]
    ang = pose[2] + phi
    return np.array([pose[0] + r * math.cos(ang), pose[1] + r * math.sin(ang)])


def inverse_observation_jacobians(pose: ArrayLike, z: ArrayLike) -> tuple[Array, Array]:
    """Jacobians of eq. (12): ∂m/∂pose (2x3) and ∂m/∂z (2x2)."""
    r, phi = z[0], z[1]
    ang = pose[2] + phi
    c, s = math.cos(ang), math.sin(ang)
    G_pose = np.array([[1.0, 0.0, -r * s], [0.0, 1.0, r * c]])
    G_z = np.array([[c, -r * s], [s, r * c]])
    return G_pose, G_z


def observation_noise(sigma_range: float, sigma_bearing: float) -> Array:
    """Q, eq. (11): diag(σ_r², σ_φ²) with σ_r in m and σ_φ in rad."""
    return np.diag([float(sigma_range) ** 2, float(sigma_bearing) ** 2])
