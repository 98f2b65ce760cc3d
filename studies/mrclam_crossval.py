"""Noise that holds on data it was not tuned on: leave-one-dataset-out tuning on MRCLAM.

`studies.mrclam_tuning.tune_noise` tunes on one dataset and scores on the same one: a
training-set score. Here every point of a grid replays every robot of several datasets once
(`measure_grid`, a `GridTable` of aligned landmark errors after eq. 17), and the folds are
arithmetic on that table, so no fold can see the data it is scored on:

- a fold tunes on all datasets but one (the grid point with the best `OBJECTIVES` score over
  the training datasets' robots, one setting for all of them) and scores its winner on the
  dataset left out (`cross_validate`); its held-out average and worst robot are the honest
  figures;
- the shipped default (`choose_default`): the objective with the lower mean held-out error over
  the folds, then the per-field median of that objective's fold winners. Each winner was chosen
  without one dataset, and the median of three grid values is a grid value, so one fold's odd
  winner cannot move it. It is never chosen by its score on all datasets at once.

`ekfslam.logs.mrclam.defaults.MRCLAM_NOISE` is this rule's choice on the table recorded in
`ekfslam.logs.mrclam.defaults.CROSSVAL_TABLE` (``python -m studies tune-mrclam --cross-validate
--out FILE``; ``--table`` reads one back).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ekfslam.analysis.parallel import run_tasks
from ekfslam.core.noise import NoiseConfig
from ekfslam.errors import InputError
from ekfslam.logs.mrclam.defaults import CROSSVAL_TABLE
from ekfslam.logs.mrclam.load import ROBOTS
from studies.mrclam_tuning import TUNING_GRID, grid_point_errors

Array = NDArray[np.float64]

#: The datasets of the cross-validation: 7 has Vicon, 1 and 4 have none (eq. 17 needs only the
#: landmarks' ground truth).
DATASETS = (7, 1, 4)
#: sigma_y for every grid point (m/√s): a differential drive does not slip sideways.
BASE = NoiseConfig(sigma_y=0.005)
#: What a fold minimises over its training robots: their mean aligned error, or the worst one
#: (a setting on the edge of a cliff, where one robot's map bends, loses under "worst").
OBJECTIVES = ("mean", "worst")


@dataclass(frozen=True, eq=False)
class GridTable:
    """Aligned landmark error (m, eq. 17) of every robot of every dataset at every grid point.

    points : the grid, one {NoiseConfig field: value} per point (P,). datasets : their labels
    (D,). robots : (R,). errors : (P, D, R) m. base : the NoiseConfig fields the grid keeps.
    """

    points: tuple[dict[str, float], ...]
    datasets: tuple[str, ...]
    robots: tuple[int, ...]
    errors: Array
    base: NoiseConfig = BASE

    def __post_init__(self) -> None:
        shape = (len(self.points), len(self.datasets), len(self.robots))
        if np.shape(self.errors) != shape:
            raise ValueError(f"errors must have shape {shape}, got {np.shape(self.errors)}")

    def noise(self, point: int) -> NoiseConfig:
        """The NoiseConfig of grid point `point`."""
        return dataclasses.replace(self.base, **self.points[point])

    def as_dict(self) -> dict:
        """The JSON form: the grid, the labels and the errors rounded to 1 µm."""
        return {
            "base": {k: v for k, v in dataclasses.asdict(self.base).items() if v is not None},
            "datasets": list(self.datasets),
            "robots": list(self.robots),
            "points": [dict(p) for p in self.points],
            "errors": np.round(np.asarray(self.errors), 6).tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict) -> GridTable:
        return cls(
            points=tuple(dict(p) for p in data["points"]),
            datasets=tuple(str(d) for d in data["datasets"]),
            robots=tuple(int(r) for r in data["robots"]),
            errors=np.asarray(data["errors"], dtype=float),
            base=NoiseConfig(**data.get("base", {})),
        )


def read_table(path: str | Path = CROSSVAL_TABLE) -> GridTable:
    """A GridTable written by `GridTable.as_dict` (``tune-mrclam --out``); InputError if not.

    path : default the recorded table `MRCLAM_NOISE` was chosen on.
    """
    path = Path(path)
    try:
        return GridTable.from_dict(json.loads(path.read_text()))
    except OSError as exc:
        raise InputError(path, None, f"cannot read it ({exc.strerror})") from None
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(path, None, f"not a tune-mrclam grid table ({exc})") from None


def grid_points(grid: Mapping[str, tuple[float, ...]]) -> tuple[dict[str, float], ...]:
    """Every combination of `grid` (field -> values), the last field varying fastest."""
    names = list(grid)
    return tuple(dict(zip(names, v, strict=True)) for v in itertools.product(*grid.values()))


def measure_grid(
    folders: Mapping[str, str | Path],
    grid: Mapping[str, tuple[float, ...]] | None = None,
    base: NoiseConfig = BASE,
    robots: tuple[int, ...] = ROBOTS,
    jobs: int | None = 1,
    dask: str | None = None,
) -> GridTable:
    """Replay every robot of every dataset at every grid point: the table the folds share.

    folders : {label: MRCLAM dataset folder}. grid : default `TUNING_GRID` (81 points; with
    Datasets 7, 1 and 4 that is 1,215 replays). jobs, dask : one task per (point, dataset),
    see `ekfslam.analysis.parallel.run_tasks`; the table is the same whatever the backend.
    """
    points = grid_points(TUNING_GRID if grid is None else grid)
    labels = tuple(folders)
    tasks = [
        (str(folders[d]), dataclasses.replace(base, **p), robots, None)
        for p in points
        for d in labels
    ]
    errors = run_tasks(grid_point_errors, tasks, jobs, dask)
    shape = (len(points), len(labels), len(robots))
    return GridTable(points, labels, robots, np.asarray(errors, dtype=float).reshape(shape), base)


@dataclass(frozen=True)
class Fold:
    """One fold: tuned on `tuned_on`, its winner scored on `scored_on` (never among them).

    winner : the grid point chosen. in_sample_mean : m, the winner's average over the training
    robots (what it was chosen by). held_out_mean, held_out_max : m, its average and worst
    robot on `scored_on`. held_out_best : m, the best average any grid point reaches on
    `scored_on` (tuning on the test data itself: what the fold gives up by not doing so).
    """

    tuned_on: tuple[str, ...]
    scored_on: str
    winner: int
    noise: dict[str, float]
    in_sample_mean: float
    held_out_mean: float
    held_out_max: float
    held_out_best: float


def folds(datasets: tuple[str, ...]) -> list[tuple[tuple[str, ...], str]]:
    """Leave one dataset out: [(the others, the one), ...], one fold per dataset."""
    if len(datasets) < 2:
        raise ValueError(f"cross-validation needs at least two datasets, got {list(datasets)}")
    return [(tuple(d for d in datasets if d != test), test) for test in datasets]


def tune(table: GridTable, datasets: tuple[str, ...], objective: str = "mean") -> int:
    """The grid point with the smallest `objective` over the robots of `datasets` only.

    objective : "mean" or "worst" (`OBJECTIVES`) aligned error of those robots. Ties go to the
    first point in grid order, so the choice is the same on every machine.
    """
    if objective not in OBJECTIVES:
        raise ValueError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    columns = [table.datasets.index(d) for d in datasets]
    seen = np.asarray(table.errors)[:, columns, :]
    score = seen.mean(axis=(1, 2)) if objective == "mean" else seen.max(axis=(1, 2))
    return int(np.argmin(score))


def cross_validate(table: GridTable, objective: str = "mean") -> list[Fold]:
    """The leave-one-dataset-out folds of `table` (see the module docstring)."""
    errors = np.asarray(table.errors)
    result = []
    for train, test in folds(table.datasets):
        winner = tune(table, train, objective)
        k = table.datasets.index(test)
        columns = [table.datasets.index(d) for d in train]
        result.append(
            Fold(
                tuned_on=train,
                scored_on=test,
                winner=winner,
                noise=dict(table.points[winner]),
                in_sample_mean=float(errors[winner, columns, :].mean()),
                held_out_mean=float(errors[winner, k, :].mean()),
                held_out_max=float(errors[winner, k, :].max()),
                held_out_best=float(errors[:, k, :].mean(axis=1).min()),
            )
        )
    return result


def held_out_mean(fold_list: list[Fold]) -> float:
    """m: the folds' held-out averages, averaged (the figure objectives are compared by)."""
    return float(np.mean([f.held_out_mean for f in fold_list]))


def choose_objective(table: GridTable, by_objective: Mapping[str, list[Fold]] | None = None) -> str:
    """The objective whose folds score best held out (ties: the first of `OBJECTIVES`).

    by_objective : each objective's `cross_validate` folds, when the caller has them already.
    """
    if by_objective is None:
        by_objective = {o: cross_validate(table, o) for o in OBJECTIVES}
    return min(OBJECTIVES, key=lambda o: held_out_mean(by_objective[o]))


def choose_default(table: GridTable, fold_list: list[Fold] | None = None) -> int:
    """The shipped default, as a grid point index: the per-field median of the fold winners.

    fold_list : default the folds of `choose_objective`. With an even number of folds the lower
    median is taken, so the result stays on the grid.
    """
    if fold_list is None:
        fold_list = cross_validate(table, choose_objective(table))
    names = list(table.points[0])
    median = {}
    for name in names:
        values = sorted(f.noise[name] for f in fold_list)
        median[name] = values[(len(values) - 1) // 2]
    return next(i for i, p in enumerate(table.points) if all(p[n] == median[n] for n in names))


def report(table: GridTable) -> dict:
    """Folds, the chosen default and its per-robot errors on every dataset, as one JSON object."""
    by_objective = {o: cross_validate(table, o) for o in OBJECTIVES}
    objective = choose_objective(table, by_objective)
    chosen = choose_default(table, by_objective[objective])
    errors = np.asarray(table.errors)
    return {
        "grid_points": len(table.points),
        "replays": int(errors.size),
        "rule": "the objective with the lower mean held-out error; the per-field median of "
        "its fold winners",
        "objectives": {
            o: {"folds": [dataclasses.asdict(f) for f in fs], "held_out_mean": held_out_mean(fs)}
            for o, fs in by_objective.items()
        },
        "objective": objective,
        "default": {
            "point": chosen,
            "noise": dict(table.points[chosen]),
            "datasets": {
                d: {
                    "robots": [round(float(e), 6) for e in errors[chosen, k]],
                    "mean": float(errors[chosen, k].mean()),
                    "max": float(errors[chosen, k].max()),
                }
                for k, d in enumerate(table.datasets)
            },
        },
    }


def report_text(table: GridTable) -> str:
    """`report` as two Markdown tables: the folds, then the default per robot and dataset."""
    r = report(table)
    lines = [
        f"leave-one-dataset-out over {len(table.datasets)} datasets x {len(table.robots)} robots, "
        f"{r['grid_points']} grid points ({r['replays']} replays); errors in m after eq. (17)",
        "",
        "| objective | tuned on | scored on | held-out avg | held-out max | in-sample avg "
        "| best avg on the held-out data | winner |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for o, fs in r["objectives"].items():
        for f in fs["folds"]:
            lines.append(
                f"| {o} | {' + '.join(f['tuned_on'])} | {f['scored_on']} "
                f"| {f['held_out_mean']:.3f} | {f['held_out_max']:.3f} "
                f"| {f['in_sample_mean']:.3f} | {f['held_out_best']:.3f} "
                f"| {_noise_text(f['noise'])} |"
            )
        lines.append(f"| {o} | mean of the folds | | {fs['held_out_mean']:.3f} | | | | |")
    d = r["default"]
    lines += [
        "",
        f"default ({r['rule']}: {r['objective']}): {_noise_text(d['noise'])}",
        "",
        "| dataset | " + " | ".join(f"robot {n}" for n in table.robots) + " | average | max |",
        "|---" * (len(table.robots) + 3) + "|",
    ]
    for name, row in d["datasets"].items():
        cells = " | ".join(f"{e:.3f}" for e in row["robots"])
        lines.append(f"| {name} | {cells} | {row['mean']:.3f} | {row['max']:.3f} |")
    return "\n".join(lines)


def _noise_text(noise: Mapping[str, float]) -> str:
    return ", ".join(f"{k} {v:g}" for k, v in noise.items())
