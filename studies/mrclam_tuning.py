"""The noise grid MRCLAM's default was chosen on, searched on one dataset (an in-sample score).

`tune_noise` replays every robot of a dataset at every point of `TUNING_GRID` with one setting for
all of them and ranks the points by the robots' average aligned error (eq. 17). It is a
training-set score: `MRCLAM_NOISE` (`ekfslam.logs.mrclam.defaults`) is chosen from the same grid by
leave-one-dataset-out cross-validation instead (`studies.mrclam_crossval`). Both run from
``python -m studies tune-mrclam``.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ekfslam.analysis.mrclam_tuning import score_robots
from ekfslam.analysis.parallel import run_tasks
from ekfslam.core.noise import NoiseConfig
from ekfslam.logs.mrclam.calibration import CommandCalibration
from ekfslam.logs.mrclam.load import ROBOTS

#: The grid `MRCLAM_NOISE` was chosen on, by `tune_noise` and then cross-validation (sigma_y fixed
#: at 0.005 m/√s: a differential drive does not slip sideways, Vicon shows < 0.01 m/s across the
#: body).
TUNING_GRID: dict[str, tuple[float, ...]] = {
    "sigma_x": (0.005, 0.01, 0.02),
    "sigma_theta": (0.03, 0.05, 0.1),
    "sigma_range": (0.15, 0.2, 0.3),
    "sigma_bearing": (0.01, 0.02, 0.05),
}


@dataclass(frozen=True)
class TuningRow:
    """One grid point: the noise tried and the aligned landmark error of each robot (m)."""

    noise: dict[str, float]
    errors: tuple[float, ...]

    @property
    def mean(self) -> float:
        return float(np.mean(self.errors))

    @property
    def worst(self) -> float:
        return float(np.max(self.errors))


def tune_noise(
    dataset_dir: str | Path,
    grid: dict[str, tuple[float, ...]] | None = None,
    base: NoiseConfig | None = None,
    robots: tuple[int, ...] = ROBOTS,
    calibration: CommandCalibration | None = None,
    jobs: int | None = 1,
    dask: str | None = None,
) -> list[TuningRow]:
    """Grid search of the noise on one dataset, minimising the robots' average aligned error.

    Every combination of `grid` (field name of `ekfslam.core.noise.NoiseConfig` -> values) replays
    every robot with the same noise: one setting for all robots, never one per robot. `base`
    gives the fields the grid does not vary (default: sigma_y 0.005 m/√s, the rest NoiseConfig's).

    jobs, dask : where the grid points go (`ekfslam.analysis.parallel.run_tasks`, one task per
    point; a worker loads each robot once and keeps it for its next points).

    Returns the rows sorted best first (by the average over the robots).
    """
    grid = TUNING_GRID if grid is None else grid
    base = base or NoiseConfig(sigma_y=0.005)
    names = list(grid)
    points = [dict(zip(names, values, strict=True)) for values in itertools.product(*grid.values())]
    folder = str(dataset_dir)
    tasks = [(folder, dataclasses.replace(base, **p), robots, calibration) for p in points]
    errors = run_tasks(grid_point_errors, tasks, jobs, dask)
    rows = [TuningRow(p, e) for p, e in zip(points, errors, strict=True)]
    return sorted(rows, key=lambda r: r.mean)


def grid_point_errors(
    dataset_dir: str, noise: NoiseConfig, robots: tuple[int, ...], calibration
) -> tuple[float, ...]:
    """Each robot's aligned error (m) at one noise setting: one grid point's task."""
    return tuple(s.aligned_error for s in score_robots(dataset_dir, noise, robots, calibration))
