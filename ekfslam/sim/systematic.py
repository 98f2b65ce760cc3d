"""The systematic errors of a real robot, as the simulator applies them (`SimulationConfig`'s
tag_position_sigma, range_scale, wheel_radius_scale, wheelbase_scale, motor_lag; slip and the
camera latency are applied where the motion and the frames are made, in
`ekfslam.sim.simulation`). Each is the identity at its default, the ideal robot.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.arena import Arena, Tag
from ekfslam.core.kinematics import MecanumGeometry
from ekfslam.sim.config import SimulationConfig

Array = NDArray[np.float64]


def true_robot(config: SimulationConfig) -> MecanumGeometry:
    """The robot's true geometry: the nominal one (run.json's) times the radius and wheelbase
    scales (`wheel_radius_scale`, `wheelbase_scale`)."""
    c = config
    if c.wheel_radius_scale == 1.0 and c.wheelbase_scale == 1.0:
        return c.robot
    r = c.robot
    return MecanumGeometry(
        r.wheel_radius * c.wheel_radius_scale, r.lx * c.wheelbase_scale, r.ly * c.wheelbase_scale
    )


def first_order(x: Array, tau_steps: float) -> Array:
    """x (N, k) through a first-order lag of time constant tau_steps control intervals.

    Row k of the result is the lagged value at the end of interval k (the input held over it,
    from rest), the speed the simulator then holds over that interval.
    """
    alpha = 1.0 - math.exp(-1.0 / tau_steps)
    out = np.empty_like(x)
    y = np.zeros(x.shape[1])
    for k, row in enumerate(x):
        y = y + alpha * (row - y)
        out[k] = y
    return out


def scaled_from_camera(
    r: Array, b: Array, mounting: ArrayLike, scale: float
) -> tuple[Array, Array]:
    """Range and bearing from the robot centre of a tag whose distance *from the camera* is
    reported `scale` times too long, its direction from the camera kept (a tag size or focal
    length that is off scales the whole camera-frame position: z = f S / s_px)."""
    mx, my = mounting[0], mounting[1]
    x, y = r * np.cos(b) - mx, r * np.sin(b) - my  # the tag from the camera, robot axes
    x, y = mx + scale * x, my + scale * y
    return np.hypot(x, y), np.arctan2(y, x)


def true_arena(config: SimulationConfig, arena: Arena, rng: np.random.Generator) -> Arena:
    """Where the tags really are: each tag moved off its map position by N(0, σ²) per axis
    (σ = `tag_position_sigma`), facing the same way; the arena itself when σ = 0."""
    offsets = config.tag_position_sigma * rng.standard_normal((len(arena.tags), 2))
    if config.tag_position_sigma == 0.0:
        return arena
    tags = tuple(
        Tag(t.id, t.position + dxy, t.normal) for t, dxy in zip(arena.tags, offsets, strict=True)
    )
    return dataclasses.replace(arena, tags=tags)
