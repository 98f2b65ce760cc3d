"""The seed's "driving multiple times" and "trade-off of the trajectory", as numbers.

`lap_statistics` scores each lap of a simulated run (the trajectory over it, the map at its end)
from one replay; `revisits` finds the moments a tag is seen again after a while (where the
uncertainty drops); `size_sweep` scores the paths at several sizes and seeds.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ekfslam.analysis.alignment import align
from ekfslam.analysis.frames_of_reference import position_errors, tags_in_filter_frame
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.history import History, Outcome
from ekfslam.errors import AlignmentError, EkfSlamError
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import NoiseConfig, batch_config, replay, replay_until_each
from ekfslam.sim.simulation import SimulationConfig, simulate

Array = NDArray[np.float64]


def lap_times(run: RunLog) -> Array:
    """End time (s) of each lap of a simulated run, from its waypoint times; shape (laps,)."""
    sim = run.meta.simulation
    if not sim or "waypoint_times" not in sim:
        raise EkfSlamError(f"run {run.meta.name!r} is not a simulated run with waypoint times")
    per_lap = 4 if sim["trajectory"] == "square" else 8
    times = np.asarray(sim["waypoint_times"], dtype=float)
    return times[per_lap::per_lap][: int(sim["laps"])]


@dataclass(frozen=True)
class LapStats:
    """Error and uncertainty over one lap (m).

    position_rmse : RMS position error over the lap's events, in the filter's frame.
    position_sd : mean over the lap of √(σ_xx + σ_yy), the robot's position uncertainty.
    map_error : eq. (17) mean distance after aligning the map at the lap's end (NaN below 2).
    map_error_unaligned : mean distance to the tags in the filter's frame at the lap's end.
    map_sd : mean over landmarks of √(trace Σ_ll) at the lap's end.
    """

    lap: int
    t_start: float
    t_end: float
    landmarks: int
    position_rmse: float
    position_sd: float
    map_error: float
    map_error_unaligned: float
    map_sd: float


def lap_statistics(
    run: RunLog, noise: NoiseConfig | None = None, config: FilterConfig | None = None
) -> tuple[LapStats, ...]:
    """Replay a simulated run once and score each lap: the trajectory over it, the map at its end.

    The map at a lap's end is `ekfslam.pipeline.replay_until` at that time, taken from the same
    pass as the full replay (`replay_until_each`).
    """
    ends = lap_times(run)
    full, at_ends = replay_until_each(run, [float(t) for t in ends], noise, config)
    h = full.history
    t_err, err = position_errors(run, h)
    sd = np.sqrt(h.pose_cov[:, 0, 0] + h.pose_cov[:, 1, 1])
    tags = tags_in_filter_frame(run)
    out = []
    for k, (t1, at_end) in enumerate(zip(ends, at_ends, strict=True)):
        t0 = 0.0 if k == 0 else float(ends[k - 1])
        lap_err = err[(t_err > t0) & (t_err <= t1)]
        lap_sd = sd[(h.t > t0) & (h.t <= t1)]
        lm = at_end.landmarks
        try:
            map_error = align(lm, run.meta.tag_map).mean_error
        except AlignmentError:
            map_error = math.nan
        unaligned = [np.hypot(*(lm[i] - tags[i])) for i in lm if i in tags]
        spread = [math.sqrt(np.trace(c)) for c in at_end.landmark_covariances.values()]
        out.append(
            LapStats(
                lap=k + 1,
                t_start=t0,
                t_end=float(t1),
                landmarks=len(lm),
                position_rmse=float(np.sqrt(np.mean(lap_err**2))) if len(lap_err) else math.nan,
                position_sd=float(lap_sd.mean()) if len(lap_sd) else math.nan,
                map_error=float(map_error),
                map_error_unaligned=float(np.mean(unaligned)) if unaligned else math.nan,
                map_sd=float(np.mean(spread)) if spread else math.nan,
            )
        )
    return tuple(out)


def revisits(history: History, gap: float = 10.0) -> tuple[Array, NDArray[np.int64]]:
    """Times (s) and ids of accepted sightings of a tag last seen more than `gap` s before.

    These are the seed's "sees landmarks it has seen before": the moments the uncertainty drops.
    """
    accepted = history.outcome_mask(Outcome.ACCEPTED, Outcome.INITIALISED)
    last: dict[int, float] = {}
    times, ids = [], []
    for t, i, ok in zip(history.obs_t.tolist(), history.obs_id.tolist(), accepted, strict=True):
        if not ok:
            continue
        if i in last and t - last[i] > gap:
            times.append(t)
            ids.append(i)
        last[i] = t
    return np.array(times, dtype=float), np.array(ids, dtype=np.int64)


@dataclass(frozen=True)
class SweepPoint:
    """One simulated run of the size sweep: path, size (m), seed, and its scores (m)."""

    trajectory: str
    size: float
    seed: int
    landmarks: int
    map_error: float  # eq. (17), mean distance after alignment; NaN with fewer than 2 landmarks
    position_rmse: float  # trajectory error in the filter's frame


def size_sweep(
    trajectories: Iterable[str] = ("square", "octagon"),
    sizes: Iterable[float] = (0.4, 0.7, 1.0),
    seeds: Iterable[int] = (1, 2),
    noise: NoiseConfig | None = None,
    laps: int = 2,
) -> tuple[SweepPoint, ...]:
    """Simulate and replay every (trajectory, size, seed) with the default simulator settings."""
    trajectories, sizes, seeds = tuple(trajectories), tuple(sizes), tuple(seeds)
    replays = len(trajectories) * len(sizes) * len(seeds)  # together they choose the backend
    out = []
    for trajectory in trajectories:
        for size in sizes:
            for seed in seeds:
                cfg = SimulationConfig(trajectory=trajectory, size=size, seed=seed, laps=laps)
                run = simulate(cfg)
                result = replay(run, noise, batch_config(run, replays))
                try:
                    error = align(result.landmarks, run.meta.tag_map).mean_error
                except AlignmentError:
                    error = math.nan
                _, err = position_errors(run, result.history)
                rmse = float(np.sqrt(np.mean(err**2)))
                point = SweepPoint(
                    trajectory, float(size), seed, len(result.landmarks), error, rmse
                )
                out.append(point)
    return tuple(out)
