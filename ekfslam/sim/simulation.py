"""A simulator of the seed's robot: it writes the run log that a real robot would record.

The robot is a mecanum base commanded by four wheel speeds (seed Section 2.2) that drives a square
or an octagon around the seed's arena (Section 1) with a forward camera that reads the AprilTags.

How a run is made, and why:

1. **Plan.** A waypoint controller turns in place to face the next waypoint, then drives forward
   with a small heading correction. It steers on the pose the robot *believes*: the nominal start
   dead-reckoned with the commanded twist and no noise. A real robot placed slightly off the
   nominal start believes it is exactly there, so its commands do not depend on the placement
   error or on wheel slip.
2. **Move.** The true robot starts at nominal start + placement error and executes the commanded
   wheel speeds plus Gaussian wheel-speed noise, held constant over each control interval and
   integrated exactly along the arc. Its true path is the commanded path moved by the start
   error, plus drift.
3. **See.** At each camera frame every tag wholly in the camera's image (its printed outline,
   white border included, through the pinhole model with its distortion, height, pitch and
   mounting: `ekfslam.core.camera.tags_in_view`, the rule the vision evaluation counts by), within
   range and not too edge-on, is detected (unless dropped out) with noisy range and bearing
   (eq. 10). Optional outliers (wrong id, gross range) exercise robust filters.
4. **Err like a real robot** (all off by default; `ekfslam.sim.config.REALISTIC` turns them on
   at defensible values; `ekfslam.sim.systematic`). The tags stand off their tag_map places
   (run.json keeps the measured map, the truth goes to ``simulation.true_tags``); the wheels
   have the true radius and wheelbase, slip and lag their commands; the camera reports
   distances `range_scale` times too long, through a lens distortion the detector leaves in
   (`lens_distortion_ignored`), turned by `camera_yaw_error`, and stamps each frame
   `camera_latency` after it saw.

Random numbers come from `numpy.random.default_rng` children of one `SeedSequence(config.seed)`,
one child per stage (start, motion, camera, tag placement, slip), and every stage draws the
same arrays whatever the rates: the same config gives identical arrays, and turning one noise
off leaves the others' draws unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam import checks
from ekfslam.core.arena import SEED_ARENA, Arena
from ekfslam.core.camera import (
    tags_in_view,
)
from ekfslam.core.kinematics import twist_to_wheels, wheels_to_twist
from ekfslam.errors import ConfigError
from ekfslam.geometry import wrap_angle
from ekfslam.logs import realistic_defaults
from ekfslam.logs.runlog import Controls, Detections, GroundTruth, RunLog, RunMeta
from ekfslam.sim.config import (  # noqa: F401  (re-exported: callers import them from here)
    DEFAULT_SIZE,
    REALISTIC_ERRORS,
    SYSTEMATIC_FIELDS,
    TRAJECTORIES,
    SimulationConfig,
    config_from_dict,
)
from ekfslam.sim.systematic import camera_errors, first_order, true_arena, true_robot

Array = NDArray[np.float64]


def waypoints(trajectory: str = "square", size: float = 0.75, laps: int = 2) -> Array:
    """Corners of the path, counter-clockwise, starting and ending at the start corner.

    square : the axis-aligned square of side `size` centred at the origin, from its lower-left
        corner (-size/2, -size/2): the default passes through the nominal start.
    octagon : the regular octagon inscribed in the square's circumcircle (circumradius
        size/√2) with the square's four corners among its vertices, from the lower-left one.
        The other four vertices lie on the axes at ±size/√2 (0.53 m by default, 0.22 m from the
        walls); the robot turns 45° at each vertex instead of 90°.

    Returns
    -------
    array (laps * n + 1, 2), m; n = 4 (square) or 8 (octagon).
    """
    if trajectory not in TRAJECTORIES:
        raise ValueError(f"trajectory must be one of {TRAJECTORIES}, got {trajectory!r}")
    n = 4 if trajectory == "square" else 8
    radius = size / math.sqrt(2.0)
    angles = math.radians(225.0) + 2.0 * math.pi * np.arange(n) / n
    corners = radius * np.column_stack([np.cos(angles), np.sin(angles)])
    if trajectory == "square":
        corners = np.round(corners / (size / 2.0)) * (size / 2.0)  # exact ±size/2, no cos error
    path = np.vstack([np.tile(corners, (int(laps), 1)), corners[:1]])
    return path


def arc_increment(theta: ArrayLike, twist: ArrayLike, dt: ArrayLike) -> Array:
    """World-frame displacement (dx, dy, dθ) of a constant body twist held for dt, exactly.

    Parameters
    ----------
    theta : () or (M,) heading at the start of the interval, rad.
    twist : (3,) or (M, 3) body twist (vx, vy, ωz), m/s, m/s, rad/s.
    dt : () or (M,) duration, s.

    Returns
    -------
    (3,) or (M, 3): the exact arc, which tends to the seed's eq. (5) as ωz dt -> 0.
    """
    v = np.asarray(twist, dtype=float)
    a = v[..., 2] * dt
    # sin(a)/a and (1 - cos a)/a, written with sinc so that a = 0 needs no special case
    s = np.sinc(a / np.pi)
    c = np.sin(a / 2.0) * np.sinc(a / (2.0 * np.pi))
    bx = (s * v[..., 0] - c * v[..., 1]) * dt
    by = (c * v[..., 0] + s * v[..., 1]) * dt
    ct, st = np.cos(theta), np.sin(theta)
    return np.stack([ct * bx - st * by, st * bx + ct * by, a], axis=-1)


def integrate_twist(start: ArrayLike, twist: ArrayLike, dt: ArrayLike) -> Array:
    """Poses (M+1, 3) from `start` (3,) after each of M constant twists (M, 3) held for dt (M,).

    Headings are returned wrapped to [-π, π).
    """
    v = np.asarray(twist, dtype=float).reshape(-1, 3)
    dt = np.broadcast_to(np.asarray(dt, dtype=float), (len(v),))
    start = np.asarray(start, dtype=float)
    theta = start[2] + np.concatenate([[0.0], np.cumsum(v[:, 2] * dt)])
    steps = arc_increment(theta[:-1], v, dt)
    xy = start[:2] + np.vstack([[0.0, 0.0], np.cumsum(steps[:, :2], axis=0)])
    return np.column_stack([xy, wrap_angle(theta)])


@dataclass(frozen=True, eq=False)
class CommandPlan:
    """What the controller commands, and where the robot believes it is.

    t : (N,) control times k / controls_hz, s.  wheels : (N, 4) commanded wheel speeds, rad/s
    (the last row is a stop).  believed : (N, 3) believed pose at each control time.
    waypoints : (K, 2) m.  waypoint_index : (K,) control index at which each waypoint was reached
    (0 for the start).
    """

    t: Array
    wheels: Array
    believed: Array
    waypoints: Array
    waypoint_index: NDArray[np.int64]


def _speed(remaining: float, previous: float, top: float, accel: float, dt: float) -> float:
    """Speed magnitude that accelerates, cruises, brakes, and lands exactly on `remaining`."""
    return min(top, previous + accel * dt, math.sqrt(2.0 * accel * remaining), remaining / dt)


#: The fields of `SimulationConfig` the controller reads: runs that agree on them (an error
#: budget's runs differ only in the seed and the systematic errors) share one plan.
_PLAN_FIELDS = (
    "trajectory",
    "size",
    "laps",
    "controls_hz",
    "max_speed",
    "max_turn_rate",
    "max_accel",
    "max_angular_accel",
    "heading_gain",
    "stop_duration",
    "robot",
)
_PLANS: dict[tuple, CommandPlan] = {}


def plan_commands(config: SimulationConfig, nominal_start: ArrayLike) -> CommandPlan:
    """Run the waypoint controller on the believed (noise-free, dead-reckoned) pose.

    The plan depends on `_PLAN_FIELDS` and the start only, so the last few are kept (read-only)
    and handed out again: a study that simulates one path many times plans it once.
    """
    key = (*(getattr(config, f) for f in _PLAN_FIELDS), *np.asarray(nominal_start, float).tolist())
    plan = _PLANS.get(key)
    if plan is None:
        plan = _plan_commands(config, nominal_start)
        for array in (plan.t, plan.wheels, plan.believed, plan.waypoints, plan.waypoint_index):
            array.setflags(write=False)
        if len(_PLANS) >= 8:
            _PLANS.pop(next(iter(_PLANS)))
        _PLANS[key] = plan
    return plan


def _plan_commands(config: SimulationConfig, nominal_start: ArrayLike) -> CommandPlan:
    c = config
    dt = 1.0 / c.controls_hz
    path = waypoints(c.trajectory, c.size, c.laps)
    pose = np.asarray(nominal_start, dtype=float).copy()
    reach = 1e-4  # m: the final step is deadbeat, so the controller lands far closer than this
    max_steps = int(1e4 * c.controls_hz)  # a safety net, never reached by a sane config
    twists, believed, reached = [], [], [0]
    target, turning, v_prev, w_prev = 1, True, 0.0, 0.0
    while target < len(path):
        if len(believed) > max_steps:
            raise RuntimeError(f"controller did not reach waypoint {target} of {c.name}")
        d = path[target] - pose[:2]
        dist = math.hypot(*d)
        err = wrap_angle(math.atan2(d[1], d[0]) - pose[2]) if dist > reach else 0.0
        along = d[0] * math.cos(pose[2]) + d[1] * math.sin(pose[2])
        if dist <= reach or (not turning and along <= reach):
            reached.append(len(believed))
            target, turning = target + 1, True
            continue
        if turning and abs(err) < 1e-9:
            turning = False
        v = w = 0.0
        if turning:
            w = math.copysign(
                _speed(abs(err), abs(w_prev), c.max_turn_rate, c.max_angular_accel, dt), err
            )
        else:
            v = _speed(along, v_prev, c.max_speed, c.max_accel, dt)
            if dist > 0.05:  # near the waypoint the bearing to it swings; hold the heading
                w = max(-c.max_turn_rate, min(c.max_turn_rate, c.heading_gain * err))
        believed.append(pose.copy())
        twists.append((v, 0.0, w))
        # the exact arc of eq. (5)'s constant twist, in scalars because this loop is the hot path
        a = w * dt
        s, k = (1.0, 0.0) if a == 0.0 else (math.sin(a) / a, 2.0 * math.sin(a / 2.0) ** 2 / a)
        cos_t, sin_t = math.cos(pose[2]), math.sin(pose[2])
        pose = pose + v * dt * np.array([cos_t * s - sin_t * k, sin_t * s + cos_t * k, 0.0])
        pose[2] = wrap_angle(pose[2] + a)
        v_prev, w_prev = v, w
    n_stop = max(1, round(c.stop_duration * c.controls_hz))
    for _ in range(n_stop):  # at rest; the last row is the stop that ends the log
        believed.append(pose.copy())
        twists.append((0.0, 0.0, 0.0))
    n = len(twists)
    return CommandPlan(
        t=np.arange(n) / c.controls_hz,
        wheels=twist_to_wheels(np.array(twists), c.robot),
        believed=np.array(believed),
        waypoints=path,
        waypoint_index=np.array(reached, dtype=np.int64),
    )


def visible(pose: ArrayLike, arena: Arena, config: SimulationConfig) -> NDArray[np.bool_]:
    """Which tags the camera can read from each pose: (F, 3) poses -> (F, n) bool.

    A tag is visible when it is fully in view of the config's camera and faces it at an
    incidence of at most max_incidence (`ekfslam.core.camera.tags_in_view`: its printed outline,
    white border included, inside the image by view_margin_px), and its range from the robot
    centre is within [camera_min_range, camera_max_range].
    """
    c = config
    p = np.asarray(pose, dtype=float).reshape(-1, 3)
    in_view = tags_in_view(
        c.camera,
        c.tags,
        c.camera_mounting,
        p,
        arena.tag_positions(),
        arena.tag_normals(),
        tag_height=c.tag_height,
        max_incidence=c.max_incidence,
        margin_px=c.view_margin_px,
    )
    d = arena.tag_positions()[None, :, :] - p[:, None, :2]  # (F, n, 2) robot -> tag
    r = np.hypot(d[..., 0], d[..., 1])
    return in_view & (r >= c.camera_min_range) & (r <= c.camera_max_range)


def _true_motion(
    config: SimulationConfig, plan: CommandPlan, true_start: Array, rng, slip_rng, t_cam
):
    """True poses at the control times and at the camera times, and the noisy wheel speeds."""
    c = config
    cmd = plan.wheels
    scale = 1.0 + c.wheel_scale_sigma * rng.standard_normal(4)
    normal = rng.standard_normal(cmd.shape)
    std = np.hypot(c.wheel_noise_sigma, c.wheel_noise_fraction * np.abs(cmd))
    moving = np.any(cmd != 0.0, axis=1, keepdims=True)
    true_wheels = np.where(moving, cmd * scale + std * normal, 0.0)
    if c.motor_lag:
        true_wheels = first_order(true_wheels, c.motor_lag * c.controls_hz)
    twist = wheels_to_twist(true_wheels, true_robot(c))
    lost = 2.0 * c.slip_fraction * slip_rng.random((len(cmd), 1))  # drawn whatever the fraction
    if c.slip_fraction:
        twist = twist * (1.0 - lost)
    # split the control intervals at camera times, so the camera sees the exact true pose
    events = np.union1d(plan.t, t_cam)
    k = np.searchsorted(plan.t, events[:-1], side="right") - 1
    poses = integrate_twist(true_start, twist[k], np.diff(events))
    return poses[np.searchsorted(events, plan.t)], poses[np.searchsorted(events, t_cam)]


def _detect(config: SimulationConfig, arena: Arena, poses: Array, t_cam: Array, rng):
    """Detections (t, id, range, bearing) from camera poses (F, 3), and the outlier counts."""
    c = config
    shape = (len(poses), len(arena.tags))
    # one draw of each kind per (frame, tag), whatever is visible: seeds stay comparable
    u_drop, u_id, u_range, u_which, u_side = (rng.random(shape) for _ in range(5))
    n_range, n_bearing = rng.standard_normal(shape), rng.standard_normal(shape)
    factor = rng.uniform(1.5, 3.0, shape)
    d = arena.tag_positions()[None, :, :] - poses[:, None, :2]
    r_true = np.hypot(d[..., 0], d[..., 1])
    b_true = np.arctan2(d[..., 1], d[..., 0]) - poses[:, None, 2]
    r_true, b_true = camera_errors(r_true, b_true, c)
    r = r_true + np.hypot(c.range_noise_sigma, c.range_noise_fraction * r_true) * n_range
    b = wrap_angle(b_true + c.bearing_noise_sigma * n_bearing)
    gross = u_range < c.outlier_range_rate
    r = np.where(gross, np.where(u_side < 0.5, r * factor, r / factor), r)
    keep = visible(poses, arena, c) & (u_drop >= c.dropout)
    ids = np.broadcast_to(arena.tag_ids, shape).copy()
    wrong = keep & (u_id < c.outlier_wrong_id_rate)
    for f, j in zip(*np.nonzero(wrong), strict=True):
        # a misread id names a tag not otherwise reported in this frame, so (t, id) stays unique
        taken = set(ids[f, keep[f] & ~wrong[f]].tolist()) | set(ids[f, :j][wrong[f, :j]].tolist())
        free = [i for i in arena.tag_ids.tolist() if i not in taken and i != ids[f, j]]
        if free:
            ids[f, j] = free[int(u_which[f, j] * len(free))]
        else:  # every other tag is already reported in this frame: nothing left to misread as
            wrong[f, j] = False
    frame, col = np.nonzero(keep)
    order = np.lexsort((ids[frame, col], frame))
    frame, col = frame[order], col[order]
    detections = Detections(
        t=t_cam[frame],
        tag_id=ids[frame, col].astype(np.int64),
        range=r[frame, col],
        bearing=np.asarray(b[frame, col], dtype=float),
    )
    counts = {"wrong_id": int(wrong.sum()), "range": int((gross & keep).sum())}
    return detections, counts


def simulate(config: SimulationConfig | None = None, arena: Arena = SEED_ARENA) -> RunLog:
    """Simulate one run of the seed's robot and return its log, ground truth included.

    Parameters
    ----------
    config : SimulationConfig, default `SimulationConfig()`.
    arena : Arena, default the seed's.

    Returns
    -------
    RunLog with wheel-speed controls (N, 4) at t = k / controls_hz (the last row a stop),
    detections at t = k / camera_hz sorted by time then tag id, ground truth (N, 3) at the
    control times, and `meta.simulation` holding the seed, the true start, the noise settings,
    the outlier counts and the whole config.
    """
    c = config if config is not None else SimulationConfig()
    checks.instance(c, SimulationConfig, "simulate: config", "e.g. SimulationConfig(laps=1)")
    checks.instance(arena, Arena, "simulate: arena", "e.g. ekfslam.SEED_ARENA")
    # later stages take later children: spawn(5)[:3] are spawn(3), so older runs stay the same
    start_rng, motion_rng, camera_rng, tag_rng, slip_rng = (
        np.random.default_rng(s) for s in np.random.SeedSequence(c.seed).spawn(5)
    )
    drawn = np.asarray(c.start_error_sigma) * start_rng.standard_normal(3)
    start_error = np.asarray(c.start_error if c.start_error is not None else drawn, dtype=float)
    nominal = np.asarray(arena.nominal_start, dtype=float)
    true_start = nominal + start_error
    true_start[2] = wrap_angle(true_start[2])
    if not arena.contains(true_start):
        raise ConfigError(
            f"simulate: the robot would start at ({true_start[0]:.3f}, {true_start[1]:.3f}) m, "
            f"outside the arena (walls at ±{arena.half_size:g} m): the start error "
            f"{start_error[:2].tolist()} m from the nominal start "
            f"{nominal[:2].tolist()} puts it through a wall"
        )
    plan = plan_commands(c, nominal)
    t_cam = np.arange(math.floor(plan.t[-1] * c.camera_hz + 1e-9) + 1) / c.camera_hz
    # a frame stamped t_cam was exposed camera_latency earlier (not before the log starts)
    t_exposed = np.maximum(t_cam - c.camera_latency, 0.0) if c.camera_latency else t_cam
    truth, cam_poses = _true_motion(c, plan, true_start, motion_rng, slip_rng, t_exposed)
    seen = true_arena(c, arena, tag_rng)
    detections, outliers = _detect(c, seen, cam_poses, t_cam, camera_rng)
    noise_names = (
        "wheel_noise_sigma",
        "wheel_noise_fraction",
        "wheel_scale_sigma",
        "start_error_sigma",
        "range_noise_sigma",
        "range_noise_fraction",
        "bearing_noise_sigma",
        "dropout",
        "outlier_wrong_id_rate",
        "outlier_range_rate",
        *SYSTEMATIC_FIELDS,
    )
    config_dict = c.to_dict()  # holds the systematic errors only when they are not ideal
    noise_names = tuple(name for name in noise_names if name in config_dict)
    simulation = {
        "seed": c.seed,
        "trajectory": c.trajectory,
        "size": c.size,
        "laps": c.laps,
        "true_start": [float(v) for v in true_start],
        "start_error": [float(v) for v in start_error],
        "noise": {name: config_dict[name] for name in noise_names},
        "outliers": outliers,
        "waypoints": plan.waypoints.tolist(),
        "waypoint_times": plan.t[plan.waypoint_index].tolist(),
        "config": config_dict,
    }
    if seen is not arena:  # the map in run.json is the measured one; this is the truth
        simulation["true_tags"] = {str(t.id): t.position.tolist() for t in seen.tags}
    meta = RunMeta(
        name=c.name,
        source="simulated",
        nominal_start=nominal.copy(),
        control_rate_hz=float(c.controls_hz),
        camera_rate_hz=float(c.camera_hz),
        robot=c.robot,
        camera_mounting=np.array(c.camera_mounting, dtype=float),
        tag_map=arena.tag_map(),
        simulation=simulation,
        # the realistic robot replays with the noise that allows for its errors (run.json keeps it)
        defaults=realistic_defaults.NAME if _is_realistic(config_dict) else None,
    )
    return RunLog(
        meta=meta,
        controls=Controls(t=plan.t.copy(), kind="wheels", values=plan.wheels.copy()),
        detections=detections,
        groundtruth=GroundTruth(t=plan.t.copy(), pose=truth),
    )


def _is_realistic(config_dict: dict) -> bool:
    """Whether a config's systematic errors are exactly `REALISTIC_ERRORS` (every source on)."""
    return {k: config_dict.get(k) for k in SYSTEMATIC_FIELDS} == REALISTIC_ERRORS
