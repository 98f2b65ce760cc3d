"""The realistic robot's error budget: how much of the map error each error source explains.

The realistic scenario (`ekfslam.sim.scenarios.realistic`) drives the seed's experiments with
every systematic error of `ekfslam.sim.config.REALISTIC` on, and its map, scored by eq. (17),
is off by 0.115-0.150 m on the square like the seed's real robot (0.153 m), and by 0.08-0.13 m
on the octagon (the seed's: 0.130 m; seeds 1-8, medians 0.134 and 0.108 m). `error_budget`
takes the sources one at a time, two ways, every run replayed with the realistic robot's noise
(`ekfslam.sim.scenarios.realistic_noise`):

- **alone**: the ideal robot with only that source on: what the source does by itself;
- **all but**: the realistic robot with only that source off: what the map gains by fixing it.

The two disagree when sources interact. Errors that are independent add roughly in
quadrature, so two sources of 3 cm each make about 4 cm, not 6. Two that feed each other do more
than add: a detection stamped late and wheels that lag their commands both put the robot, in
the filter's belief, ahead of where it saw the tag, and on the square the wheels' small scale
errors then cost several times what they cost alone. Every run keeps the experiment's seed,
so the same random draws come back in each row, and only the named source changes between two
rows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ekfslam.analysis.evaluation import summarize
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.noise import NoiseConfig
from ekfslam.errors import EkfSlamError
from ekfslam.pipeline import batch_config, replay
from ekfslam.sim.config import REALISTIC
from ekfslam.sim.scenarios import realistic, realistic_noise
from ekfslam.sim.simulation import SimulationConfig, simulate


@dataclass(frozen=True)
class BudgetRow:
    """One error source's share of the map error (m, eq. 17's mean distance after alignment).

    source : its name in `REALISTIC`.  field, value : the `SimulationConfig` field and the
    realistic value.  why : the value's justification.  alone : the map error with only this
    source on.  all_but : with every source on but this one.
    """

    source: str
    field: str
    value: float
    why: str
    alone: float
    all_but: float


@dataclass(frozen=True)
class ErrorBudget:
    """The budget of one trajectory: the ideal and realistic robots and a row per source (m).

    ideal : the map error with no source on.  realistic : with every source on.
    seeds : the simulation seeds the errors are averaged over.
    realistic_by_seed : the realistic robot's map error on each seed, in the order of `seeds`
        (its spread: one seed's map is one draw of the tags, the slip and the noise).
    """

    trajectory: str
    seeds: tuple[int, ...]
    ideal: float
    realistic: float
    rows: tuple[BudgetRow, ...]
    realistic_by_seed: tuple[float, ...] = ()

    def row(self, source: str) -> BudgetRow:
        """The row of one source, by its name."""
        for r in self.rows:
            if r.source == source:
                return r
        raise KeyError(f"no error source {source!r}; known: {[r.source for r in self.rows]}")


def map_error(
    config: SimulationConfig,
    noise: NoiseConfig | None = None,
    filter_config: FilterConfig | None = None,
    replays: int = 1,
) -> float:
    """Simulate `config`, replay it and return the average aligned map error of eq. (17) (m).

    noise : default the realistic robot's (`realistic_noise`), whichever sources are on, so
    that rows of a budget differ only in the robot. replays : how many replays like this one
    the budget makes (`batch_config`).
    """
    run = simulate(config)
    noise = realistic_noise() if noise is None else noise
    summary = summarize(run, replay(run, noise, batch_config(run, replays, filter_config)))
    if summary.alignment is None:
        raise EkfSlamError(f"{run.meta.name}: no alignment ({summary.alignment_note})")
    return float(summary.alignment.mean_error)


def error_budget(
    trajectory: str,
    sources: Sequence[str] | None = None,
    seeds: Sequence[int] | None = None,
    noise: NoiseConfig | None = None,
    filter_config: FilterConfig | None = None,
) -> ErrorBudget:
    """Each error source alone and all but it, on the seed's experiment of `trajectory`.

    Parameters
    ----------
    trajectory : "square" or "octagon" (two laps, the seed's start error; `realistic`).
    sources : names in `REALISTIC` (default all); the realistic robot has exactly these on.
    seeds : simulation seeds, the errors averaged over them (default the experiment's one).
    noise, filter_config : what the filter replays with, the same in every row (default the
        realistic robot's, `realistic_noise`: the noise a student would run this robot with).

    Returns
    -------
    ErrorBudget, with 2 + 2 len(sources) simulations and replays per seed.
    """
    names = tuple(REALISTIC) if sources is None else tuple(sources)
    realistic(trajectory, names)  # refuses an unknown source or trajectory by name, up front
    seeds = (realistic(trajectory).seed,) if seeds is None else tuple(int(s) for s in seeds)
    noise = realistic_noise() if noise is None else noise
    if not seeds:
        raise ValueError("error_budget needs at least one seed")

    replays = (2 + 2 * len(names)) * len(seeds)

    def by_seed(on: Sequence[str]) -> tuple[float, ...]:
        return tuple(
            map_error(realistic(trajectory, tuple(on), seed=s), noise, filter_config, replays)
            for s in seeds
        )

    def mean_error(on: Sequence[str]) -> float:
        return float(np.mean(by_seed(on)))

    rows = tuple(
        BudgetRow(
            source=name,
            field=REALISTIC[name].field,
            value=REALISTIC[name].value,
            why=REALISTIC[name].why,
            alone=mean_error((name,)),
            all_but=mean_error([n for n in names if n != name]),
        )
        for name in names
    )
    every = by_seed(names)
    return ErrorBudget(trajectory, seeds, mean_error(()), float(np.mean(every)), rows, every)
