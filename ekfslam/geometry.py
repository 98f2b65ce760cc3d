"""Angles and planar rigid transforms shared by every other module.

Every angle and every angle difference in ekfslam is wrapped to [-π, π).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

TWO_PI = 2.0 * math.pi


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64] | float:
    """Wrap an angle (rad), or an array of them, to [-π, π): the one angle wrap of ekfslam.

    A float in gives a float out, an array an array. The same two lines run in plain Python and
    compiled inside the filter (`ekfslam.core.filter.compile`), so it takes no list: give an array.
    """
    wrapped = (angle + math.pi) % TWO_PI - math.pi
    return wrapped - TWO_PI * (wrapped >= math.pi)  # rounding can land exactly on +π: that is -π


def rotation(theta: float) -> NDArray[np.float64]:
    """The 2x2 rotation matrix R(θ) that turns body-frame vectors into the world frame."""
    c, s = math.cos(theta), math.sin(theta)
    return np.array(((c, -s), (s, c)))


def compose(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """SE(2) composition a ⊕ b of poses (x, y, θ): b is given in a's frame."""
    ax, ay, at = np.asarray(a, dtype=float)
    bx, by, bt = np.asarray(b, dtype=float)
    c, s = math.cos(at), math.sin(at)
    return np.array([ax + c * bx - s * by, ay + s * bx + c * by, wrap_angle(at + bt)])


def invert(a: ArrayLike) -> NDArray[np.float64]:
    """SE(2) inverse ⊖a of a pose (x, y, θ)."""
    ax, ay, at = np.asarray(a, dtype=float)
    c, s = math.cos(at), math.sin(at)
    return np.array([-c * ax - s * ay, s * ax - c * ay, wrap_angle(-at)])


def transform_points(pose: ArrayLike, points: ArrayLike) -> NDArray[np.float64]:
    """Apply the transform `pose` = (x, y, θ) to points of shape (N, 2): R(θ) p + (x, y)."""
    x, y, t = np.asarray(pose, dtype=float)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    return pts @ rotation(t).T + np.array([x, y])


def weighted_kabsch(
    X: NDArray[np.float64], Y: NDArray[np.float64], w: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Minimise Σ w_i ‖R(θ) X_i + t − Y_i‖² in closed form; returns (x, y, θ).

    In 2-D the optimal angle is atan2 of the weighted cross and dot sums of the centred points,
    which is always a proper rotation (no SVD, no reflection fix needed).
    """
    w = w / w.sum()
    x_bar, y_bar = w @ X, w @ Y
    A, B = X - x_bar, Y - y_bar
    cross = float(w @ (A[:, 0] * B[:, 1] - A[:, 1] * B[:, 0]))
    dot = float(w @ (A[:, 0] * B[:, 0] + A[:, 1] * B[:, 1]))
    theta = math.atan2(cross, dot)  # atan2(0, 0) = 0 when the rotation is undetermined
    t = y_bar - rotation(theta) @ x_bar
    return np.array([t[0], t[1], theta])
