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
