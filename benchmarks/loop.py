"""A user's own loop through the filter's public step API, against ukfm's EKF on ukfm's world.

``python -m benchmarks loop [--runs N] [--steps N] [--json]`` replays ukfm's 2D SLAM benchmark
(`benchmarks.ukfm_slam2d`: 20 runs of 2,500 steps, 2 to 3 sightings a step) through
`EKFSLAM.predict_many`, `EKFSLAM.update`, `EKFSLAM.pose` and `EKFSLAM.pose_covariance` every
step, as a robot's online loop or a student's loop calls them, with the default config and with
``backend="numba"`` named, FEJ and invariant; and through ukfm's own EKF loop, reimplemented
faithfully (`benchmarks.ukfm_slam2d.run_ukfm_ekf`); and PythonRobotics' EKF SLAM on its own
world (`benchmarks.pythonrobotics_ekf`: 4 tags, 500 steps of 0.1 s, its own association)
against the same user's loop on that world, ids given. ukfm's sighting is the landmark's position
in the robot's frame with noise σ² I; the loop hands the filter its range and bearing, with Q
= σ² diag(1, 1/r²) (the same noise, to first order).

Every filter runs every run once, interleaved (a busy machine slows all alike); a figure is the
median over runs of µs per step, and the ratio is ukfm's median over each one's. The position
RMSE per filter says they solve the same problem.
"""

from __future__ import annotations

import datetime
import math
import os
import statistics
import time
from collections.abc import Callable

import numpy as np

from benchmarks import pythonrobotics_ekf as pr
from benchmarks.ukfm_slam2d import DT, OBS_STD, ODO_STD, STEPS, World, run_ukfm_ekf, simulate
from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig

RUNS = 20

#: the filters of the user's loop, by their row's name: the config each is built with
CONFIGS: dict[str, FilterConfig] = {
    "ekfslam default": FilterConfig(),
    "ekfslam numba": FilterConfig(backend="numba"),
    "ekfslam fej": FilterConfig(linearization="fej"),
    "ekfslam invariant": FilterConfig(linearization="invariant"),
}
UKFM = "ukfm ekf (reimplemented)"
#: PythonRobotics' world: its loop, and the user's loop through ekfslam's default config
PR, PR_OURS = "pythonrobotics ekf_slam (reimplemented)", "ekfslam default, on its world"
PR_RUNS = 5


def run_user_loop(world: World, config: FilterConfig) -> np.ndarray:
    """The user's loop on one world: predict_many, an update per sighting, the pose and its
    covariance read every step. Returns the poses (N, 3)."""
    M = np.diag((ODO_STD[0] ** 2, 1e-12, ODO_STD[1] ** 2))  # per second: (v dt, 0, ω dt)
    f = EKFSLAM(np.zeros(3), config=config, record=False)
    ys, omegas = world.ys, world.omegas
    out = np.zeros((len(ys), 3))
    dts = np.array([DT])
    sigma2 = OBS_STD**2
    for n in range(1, len(ys)):
        v, w = omegas[n - 1]
        t = n * DT
        f.predict_many(np.array([[v * DT, 0.0, w * DT]]), dts, np.array([t]), M=M)
        y_n = ys[n]
        for x, y, i in y_n[y_n[:, 2] >= 0].tolist():  # the landmarks seen at this step
            r = math.hypot(x, y)
            Q = np.array([[sigma2, 0.0], [0.0, sigma2 / (r * r)]])
            f.update(int(i), np.array([r, math.atan2(y, x)]), Q, t)
        out[n] = f.pose
        f.pose_covariance  # noqa: B018 (read every step, as the user's loop does)
    return out


def run_user_loop_pr(world: pr.World) -> np.ndarray:
    """The user's loop on PythonRobotics' world, as `run_user_loop`: the control (v, ω) over
    DT as the body increment (v DT, 0, ω DT), its noise R_sim per second, Q_sim per sighting.
    The start is known (Σ0 = 0): PythonRobotics starts at P0 = I, which lets the whole map and
    path shift together, far off the true path's frame in which the RMSE is taken."""
    M = np.diag((pr.R_sim[0, 0] * pr.DT, 1e-12, pr.R_sim[1, 1] * pr.DT))
    Q = pr.Q_sim.copy()
    f = EKFSLAM(
        np.zeros(3), record=False
    )  # a known start (PythonRobotics' P0 = I only shifts the map)
    out = np.zeros((len(world.poses), 3))
    dts = np.array([pr.DT])
    for n, ((v, w), z) in enumerate(zip(world.inputs, world.sightings, strict=True)):
        t = (n + 1) * pr.DT
        f.predict_many(np.array([[v * pr.DT, 0.0, w * pr.DT]]), dts, np.array([t]), M=M)
        for r, b, i in z:
            f.update(int(i), np.array([r, b]), Q, t)
        out[n + 1] = f.pose
        f.pose_covariance  # noqa: B018 (read every step, as the user's loop does)
    return out


def _rmse(estimate: np.ndarray, world: World) -> float:
    d = estimate[:, :2] - world.poses[:, :2]
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1))))


def bench_loop(runs: int = RUNS, steps: int = STEPS) -> dict:
    """The figures of the module: µs per step (median over runs) per filter, ratios to ukfm,
    position RMSE (m, median over runs)."""
    filters: dict[str, Callable[[World], np.ndarray]] = {
        name: (lambda w, c=config: run_user_loop(w, c)) for name, config in CONFIGS.items()
    }
    filters[UKFM] = run_ukfm_ekf
    warm = simulate(10_000, 50)
    for run in filters.values():  # load (or compile) each backend before timing
        run(warm)
    per_step: dict[str, list[float]] = {name: [] for name in filters}
    rmse: dict[str, list[float]] = {name: [] for name in filters}
    sightings = 0
    for seed in range(runs):
        world = simulate(seed, steps)
        sightings += int((world.ys[1:, :, 2] >= 0).sum())
        for name, run in filters.items():
            t0 = time.perf_counter()
            estimate = run(world)
            per_step[name].append((time.perf_counter() - t0) / (steps - 1) * 1e6)
            rmse[name].append(_rmse(estimate, world))
    for seed in range(PR_RUNS):  # PythonRobotics' world: 500 steps a run
        world = pr.simulate(seed)
        for name, run in ((PR, pr.run_pythonrobotics), (PR_OURS, run_user_loop_pr)):
            t0 = time.perf_counter()
            estimate = run(world)
            per_step.setdefault(name, []).append(
                (time.perf_counter() - t0) / len(world.inputs) * 1e6
            )
            d = estimate[:, :2] - world.poses[:, :2]
            rmse.setdefault(name, []).append(float(np.sqrt(np.mean(np.sum(d * d, axis=1)))))
    us = {name: statistics.median(v) for name, v in per_step.items()}
    return {
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "load": os.getloadavg()[0],
        "runs": runs,
        "steps": steps,
        "us_per_step": us,
        "us_per_step_range": {name: (min(v), max(v)) for name, v in per_step.items()},
        "ukfm_over": {name: us[UKFM] / us[name] for name in filters},
        # a step's events as a replay counts them: its prediction and its sightings
        "events_per_step": 1.0 + sightings / (runs * (steps - 1)),
        "pythonrobotics_over_ours": us[PR] / us[PR_OURS],
        "position_rmse_m": {name: statistics.median(v) for name, v in rmse.items()},
        "command": f"python -m benchmarks loop --runs {runs} --steps {steps}",
    }


def loop_table(r: dict) -> str:
    """The figures as a markdown table."""
    lines = [
        f"User's loop on ukfm's 2D SLAM world: {r['runs']} runs x {r['steps']} steps "
        f"({r['date']}, load {r['load']:.2f}; `{r['command']}`)",
        "",
        "| filter | µs/step (median) | range over runs | ukfm / it | position RMSE (m) |",
        "|---|---|---|---|---|",
    ]
    for name, us in r["us_per_step"].items():
        lo, hi = r["us_per_step_range"][name]
        ratio = f"{r['ukfm_over'][name]:.2f}x" if name in r["ukfm_over"] else "–"
        lines.append(
            f"| {name} | {us:.1f} | {lo:.1f}-{hi:.1f} | {ratio} | "
            f"{r['position_rmse_m'][name]:.3f} |"
        )
    per_event = r["us_per_step"]["ekfslam default"] / r["events_per_step"]
    lines.append(
        f"\nThe default config's loop: {per_event:.2f} µs per event "
        f"({r['events_per_step']:.2f} events a step: one prediction and the sightings)"
    )
    lines.append(
        f"\nOn PythonRobotics' world ({PR_RUNS} runs x 500 steps), its EKF SLAM over the user's "
        f"loop: {r['pythonrobotics_over_ours']:.2f}x"
    )
    return "\n".join(lines)
