"""A simulated team: several of the seed's robots in one arena, on one clock, seeing one another.

Each robot is `simulate`'s (its own path, seed, placement error and landmark sightings); what a
team adds is each camera's sightings of the other robots' centres (`RobotSightings`), drawn from
the true poses at the observer's camera times: in the camera's horizontal field of view and
range, dropped as a tag is (``dropout``), with the config's range and bearing noise. The robots
drive concentric squares (or octagons) of different sizes, each from its own lower-left corner,
so they see one another across the arena. Robots do not collide: the simulator has no bodies.

The truth of each robot is its run's ground truth, so the team's consistency (NEES of every
robot's pose, of the map) is measured against it (`tests/sim/test_team_sim.py`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from ekfslam.core.arena import SEED_ARENA, Arena
from ekfslam.geometry import wrap_angle
from ekfslam.logs.team import RobotSightings, TeamLog
from ekfslam.sim.config import SimulationConfig
from ekfslam.sim.simulation import simulate

#: The paths' sizes (m, the side of each robot's square): 0.25 m apart, inside the seed's arena.
TEAM_SIZES = (0.5, 0.75, 1.0)


def simulate_team(
    sizes: Sequence[float] = TEAM_SIZES,
    config: SimulationConfig | None = None,
    arena: Arena = SEED_ARENA,
) -> TeamLog:
    """Simulate one robot per entry of `sizes` (1 to 5 robots), numbered from 1.

    Robot k drives `config`'s trajectory with side ``sizes[k - 1]``, seed ``config.seed * 10 +
    k`` (its own noise and placement error), from the nominal start (-size/2, -size/2, 0).

    Returns
    -------
    TeamLog whose runs are `simulate`'s, and whose sightings are drawn as the module says.
    """
    c = config if config is not None else SimulationConfig()
    if not 1 <= len(sizes) <= 5:
        raise ValueError(f"simulate_team: 1 to 5 robots, got {len(sizes)} sizes")
    runs = {}
    for k, size in enumerate(sizes, start=1):
        robot = dataclasses.replace(c, size=float(size), seed=c.seed * 10 + k)
        start = np.array([-size / 2.0, -size / 2.0, 0.0])
        runs[k] = simulate(robot, dataclasses.replace(arena, nominal_start=start))
    return TeamLog(name=f"team-{c.name}", runs=runs, sightings=_sightings(runs, c))


def _sightings(runs: dict, config: SimulationConfig) -> RobotSightings:
    rng = np.random.default_rng(np.random.SeedSequence([config.seed, 2]))
    half_fov = config.camera.horizontal_fov / 2.0
    rows = []
    for a, run in runs.items():
        end = run.groundtruth.t[-1]  # the camera's frames, as `simulate` times them
        t = np.arange(math.floor(end * config.camera_hz + 1e-9) + 1) / config.camera_hz
        pa = _poses_at(run, t)
        for b, other in runs.items():
            if b == a:
                continue
            pb = _poses_at(other, t)
            d = pb[:, :2] - pa[:, :2]
            r = np.hypot(d[:, 0], d[:, 1])
            bearing = wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - pa[:, 2])
            inside = (t <= other.groundtruth.t[-1]) & (abs(bearing) <= half_fov)
            inside &= (r >= config.camera_min_range) & (r <= config.camera_max_range)
            drop = rng.random(len(t))  # one draw of each kind per frame, seen or not
            n_r, n_b = rng.standard_normal(len(t)), rng.standard_normal(len(t))
            keep = inside & (drop >= config.dropout)
            z_r = r + config.range_noise_sigma * n_r
            z_b = wrap_angle(bearing + config.bearing_noise_sigma * n_b)
            for k in np.flatnonzero(keep):
                rows.append((t[k], a, b, z_r[k], z_b[k]))
    rows.sort(key=lambda row: (row[0], row[1], row[2]))
    if not rows:
        return RobotSightings.empty()
    table = np.array(rows)
    return RobotSightings(
        t=table[:, 0].copy(),
        observer=table[:, 1].astype(np.int64),
        target=table[:, 2].astype(np.int64),
        range=table[:, 3].copy(),
        bearing=np.asarray(table[:, 4], dtype=float),
    )


def _poses_at(run, t: np.ndarray) -> np.ndarray:
    """True poses at times t, interpolated between the ground truth's samples at the control
    rate (a chord of at most 1e-4 m at the seed's speeds), held at the last after the run."""
    gt = run.groundtruth
    heading = np.unwrap(gt.pose[:, 2])
    columns = [np.interp(t, gt.t, gt.pose[:, i]) for i in (0, 1)] + [np.interp(t, gt.t, heading)]
    poses = np.column_stack(columns)
    poses[:, 2] = wrap_angle(poses[:, 2])
    return poses
