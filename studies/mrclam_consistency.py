"""The noise for consistency on MRCLAM: a grid searched for pose NEES near 3 that keeps the map.

`tune_for_consistency` replays every robot of a dataset at every point of `CONSISTENCY_GRID` and
ranks the points by how far each robot's mean pose NEES against Vicon is from 3
(`ekfslam.analysis.mrclam_consistency.robot_nees`), among those whose maps stay within
`MAP_TARGETS`. It chose `ekfslam.logs.mrclam.defaults.MRCLAM_CONSISTENT_NOISE` on Dataset 7:
``tune_for_consistency(find_dataset(7))`` from a checkout's root, about two minutes on one core.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ekfslam.analysis.mrclam_consistency import IDEAL, robot_nees
from ekfslam.analysis.mrclam_tuning import load_robot
from ekfslam.analysis.parallel import run_tasks
from ekfslam.core.noise import NoiseConfig
from ekfslam.logs.mrclam.load import ROBOTS

#: The grid `tune_for_consistency` searched for `MRCLAM_CONSISTENT_NOISE`: MRCLAM_NOISE's values
#: and larger ones, since the map-tuned noise is overconfident on every robot.
CONSISTENCY_GRID: dict[str, tuple[float, ...]] = {
    "sigma_x": (0.02, 0.05, 0.1, 0.2),
    "sigma_y": (0.005, 0.05),
    "sigma_theta": (0.05, 0.1, 0.2),
    "sigma_range": (0.3, 0.5),
    "sigma_bearing": (0.01, 0.03),
}
#: The MRCLAM issue's map targets (m): every robot's aligned error, and their average.
MAP_TARGETS = (0.10, 0.07)


@dataclass(frozen=True)
class ConsistencyRow:
    """One grid point: the noise tried and, per robot, pose NEES mean and aligned error (m)."""

    noise: dict[str, float]
    nees: tuple[float, ...]
    aligned_error: tuple[float, ...]

    @property
    def mean_nees(self) -> float:
        return float(np.mean(self.nees))

    @property
    def mean_error(self) -> float:
        return float(np.mean(self.aligned_error))

    @property
    def distance(self) -> float:
        """|log(mean NEES / 3)| averaged over the robots: 0 when every robot averages 3."""
        return float(np.mean(np.abs(np.log(np.asarray(self.nees) / IDEAL))))

    def meets(self, targets: tuple[float, float] = MAP_TARGETS) -> bool:
        """Every robot's aligned error <= targets[0] m and their average <= targets[1] m."""
        return max(self.aligned_error) <= targets[0] and self.mean_error <= targets[1]


def tune_for_consistency(
    dataset_dir: str | Path,
    grid: dict[str, tuple[float, ...]] | None = None,
    base: NoiseConfig | None = None,
    robots: tuple[int, ...] = ROBOTS,
    linearization: str = "standard",
    map_targets: tuple[float, float] | None = MAP_TARGETS,
    jobs: int | None = 1,
    dask: str | None = None,
) -> list[ConsistencyRow]:
    """Grid search of the noise for consistency: one setting for every robot.

    Each combination of `grid` (NoiseConfig field -> values; default `CONSISTENCY_GRID`, about
    two minutes on one core) replays every robot. Rows come back best first: those that meet
    `map_targets` (see `ConsistencyRow.meets`; None: no constraint) before those that do not,
    each group by `ConsistencyRow.distance`, so an over- and an under-confident robot do not
    cancel out. jobs, dask : where the grid points go (`ekfslam.analysis.parallel.run_tasks`,
    one task per point); the rows are the same whatever the backend.
    """
    grid = CONSISTENCY_GRID if grid is None else grid
    base = base or NoiseConfig(sigma_y=0.005)
    points = [dict(zip(grid, v, strict=True)) for v in itertools.product(*grid.values())]
    tasks = [
        (str(dataset_dir), dataclasses.replace(base, **p), robots, linearization) for p in points
    ]
    found = run_tasks(_consistency_point, tasks, jobs, dask)
    rows = [
        ConsistencyRow(p, nees_means, errors)
        for p, (nees_means, errors) in zip(points, found, strict=True)
    ]
    return sorted(
        rows, key=lambda r: (map_targets is not None and not r.meets(map_targets), r.distance)
    )


def _consistency_point(dataset_dir, noise, robots, linearization):
    found = [robot_nees(load_robot(dataset_dir, r), noise, linearization) for r in robots]
    return tuple(f.mean for f in found), tuple(f.aligned_error for f in found)
