"""The systematic errors of a real robot, as the simulator applies them (`SimulationConfig`'s
tag_position_sigma, range_scale, lens_distortion_ignored, camera_yaw_error, wheel_radius_scale,
wheelbase_scale, motor_lag; slip and the
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


def through_lens(
    r: Array, b: Array, mounting: ArrayLike, distortion: ArrayLike
) -> tuple[Array, Array]:
    """Range and bearing from the robot centre of a tag seen through a lens whose radial
    distortion (k1, k2, OpenCV's) the detector does not undo: the tag's direction in the image
    is moved by the distortion, x' -> x' (1 + k1 ρ² + k2 ρ⁴), and the tag looks smaller by the
    lens's local magnification there (tangential 1 + k1 ρ² + k2 ρ⁴, radial 1 + 3 k1 ρ² + 5 k2
    ρ⁴; their geometric mean), so its range comes out long by that much. ρ is the tag's
    off-axis offset x' = tan(its bearing from the camera's optical axis), the camera at the
    mounting's (x, y, yaw) in the robot frame."""
    k1, k2 = float(distortion[0]), float(distortion[1])
    mx, my = mounting[0], mounting[1]
    yaw = float(mounting[2])
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = r * np.cos(b) - mx, r * np.sin(b) - my  # the tag from the camera, robot axes
    x, y = c * x + s * y, -s * x + c * y  # camera axes: x along the optical axis
    slope = y / np.maximum(x, 1e-3)
    rho2 = slope * slope
    tangential = 1.0 + rho2 * (k1 + k2 * rho2)
    radial = 1.0 + rho2 * (3.0 * k1 + 5.0 * k2 * rho2)
    d = np.hypot(x, y) / np.sqrt(np.maximum(tangential * radial, 0.25))
    angle = np.arctan(slope * tangential) + yaw  # back to robot axes
    x, y = mx + d * np.cos(angle), my + d * np.sin(angle)
    return np.hypot(x, y), np.arctan2(y, x)


def camera_errors(r: Array, b: Array, config: SimulationConfig) -> tuple[Array, Array]:
    """The true range and bearing (from the robot centre, eq. 10) as the realistic camera
    reports them: `range_scale` (`scaled_from_camera`), the lens's distortion left in
    (`through_lens`, `lens_distortion_ignored` times the camera's k1, k2) and a camera turned
    `camera_yaw_error` to the left, which sees every tag that much to the right."""
    c = config
    if c.range_scale != 1.0:
        r, b = scaled_from_camera(r, b, c.camera_mounting, c.range_scale)
    if c.lens_distortion_ignored:
        k = c.lens_distortion_ignored * np.asarray(c.camera.distortion[:2])
        r, b = through_lens(r, b, c.camera_mounting, k)
    return r, b - c.camera_yaw_error


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
