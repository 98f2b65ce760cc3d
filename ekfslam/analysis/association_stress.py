"""Data association under stress (issue 16): close pairs of tags and a drifting loop.

`stress_study` simulates the ``stress`` scenario (`ekfslam.sim.scenarios.scenario`: 8 pairs of
tags 0.3 m apart, two laps with the heading drifting by tenths of a radian), with the filter's
noise the simulator's own (`noise_for_simulation`), and replays each run three times: with the
ids (``known``), and with them hidden, by nearest neighbour (``nn``) and by joint
compatibility (``jcbb``). For each it reports the share of sightings associated correctly
(`ekfslam.core.association.Confusion.correct_fraction`) and the aligned map error of eq. (17),
the landmarks matched through the association's mapping (`ekfslam.analysis.association.score`).

For the picture (`ekfslam.viz.association.plot_wrong_associations`) it keeps, of the first run,
every wrong association as a segment from where the robot truly was to the true tag the
sighting was used as.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ekfslam.analysis import association as assoc
from ekfslam.analysis.evaluation import summarize
from ekfslam.analysis.parallel import run_tasks
from ekfslam.core.association import UNPAIRED, AssociationConfig
from ekfslam.pipeline import batch_config, replay
from ekfslam.sim.scenarios import noise_for_simulation, scenario
from ekfslam.sim.simulation import simulate

Array = NDArray[np.float64]

METHODS = ("known", "nn", "jcbb")


@dataclass(frozen=True)
class StressCase:
    """One method on one run: correct_fraction (1 for known), correct, wrong and missed
    sightings (0 for known), aligned_error (m, eq. 17; None if the map could not be aligned),
    landmarks (how many the map kept)."""

    method: str
    correct_fraction: float | None
    correct: int
    wrong: int
    missed: int
    aligned_error: float | None
    landmarks: int


@dataclass(frozen=True)
class StressStudy:
    """`stress_study`'s result.

    seeds : the runs' seeds. cases : {method: [StressCase per seed]}. detections : per seed.
    tags : {true id: (x, y)} of the first run. path : (N, 2) its true path. wrong : {method:
    (k, 2, 2)} its wrong associations, each [robot position, true tag it was used as].
    """

    seeds: list[int]
    cases: dict[str, list[StressCase]]
    detections: list[int]
    tags: dict[int, Array]
    path: Array
    wrong: dict[str, Array]

    def mean(self, method: str, key: str) -> float | None:
        """The mean of a StressCase field over the runs (None if any run has none)."""
        values = [getattr(c, key) for c in self.cases[method]]
        return None if any(v is None for v in values) else float(np.mean(values))

    def as_dict(self) -> dict:
        """JSON-ready: seeds, detections, per method its runs and their means."""
        out: dict = {"scenario": "stress", "seeds": self.seeds, "detections": self.detections}
        for m, cases in self.cases.items():
            out[m] = {
                "runs": [c.__dict__ for c in cases],
                "correct_fraction": self.mean(m, "correct_fraction"),
                "aligned_error": self.mean(m, "aligned_error"),
                "wrong_in_first_run": len(self.wrong.get(m, ())),
            }
        return out


def stress_study(
    runs: int = 1, first_seed: int = 2, jobs: int | None = 1, dask: str | None = None
) -> StressStudy:
    """Replay `runs` stress runs (seeds first_seed, first_seed + 1 ...) with known, nn, jcbb.

    jobs, dask : where the runs go (`ekfslam.analysis.parallel.run_tasks`, one task per seed;
    the same numbers whatever the backend).
    """
    if runs < 1:
        raise ValueError(f"runs must be at least 1, got {runs}")
    seeds = list(range(first_seed, first_seed + runs))
    replays = len(seeds) * len(METHODS)  # together they choose the backend (`batch_config`)
    tasks = [(seed, k == 0, replays) for k, seed in enumerate(seeds)]
    done = run_tasks(_stress_run, tasks, jobs, dask)
    cases = {m: [d[0][m] for d in done] for m in METHODS}
    detections = [d[1] for d in done]
    wrong, tags, path = done[0][2]
    return StressStudy(seeds, cases, detections, tags, path, wrong)


def _stress_run(seed: int, first: bool, replays: int = 1):
    """One task of `stress_study`: ({method: StressCase}, detections, the first run's picture).

    The picture (wrong segments per method, tag map, true path) only when `first`, else empty.
    """
    config, arena = scenario("stress", seed=seed)
    run = simulate(config, arena)
    noise = noise_for_simulation(config)
    cases: dict[str, StressCase] = {}
    wrong: dict[str, Array] = {}
    for method in METHODS:
        if method == "known":
            result = replay(run, noise, batch_config(run, replays))
            found = None
        else:
            association = AssociationConfig(method=method)
            batch = batch_config(run, replays, association=association)
            result = replay(run, noise, batch, association=association)
            result, found = assoc.score(run, result)
            if first:
                wrong[method] = wrong_segments(run, result.association.estimated, found.mapping)
        alignment = summarize(run, result).alignment
        cases[method] = StressCase(
            method=method,
            correct_fraction=1.0 if found is None else found.correct_fraction,
            correct=len(run.detections.t) if found is None else found.correct,
            wrong=0 if found is None else found.wrong,
            missed=0 if found is None else found.missed,
            aligned_error=None if alignment is None else float(alignment.mean_error),
            landmarks=len(result.landmarks),
        )
    tags: dict[int, Array] = {}
    path = np.zeros((0, 2))
    if first:
        tags = {int(i): np.asarray(p, dtype=float) for i, p in run.meta.tag_map.items()}
        path = np.asarray(run.groundtruth.pose[:, :2], dtype=float)
    return cases, len(run.detections.t), (wrong, tags, path)


def wrong_segments(run, estimated, mapping: dict[int, int]) -> Array:
    """(k, 2, 2): for each sighting used as a landmark whose true id is not its own, the
    robot's true position then and the true position of the tag it was taken for."""
    truth = np.asarray(run.detections.tag_id, dtype=int)
    t = np.asarray(run.detections.t, dtype=float)
    gt = run.groundtruth
    x = np.interp(t, gt.t, gt.pose[:, 0])
    y = np.interp(t, gt.t, gt.pose[:, 1])
    tags = run.meta.tag_map
    out = [
        [[x[i], y[i]], list(tags[mapping[int(e)]])]
        for i, e in enumerate(np.asarray(estimated, dtype=int).tolist())
        if e != UNPAIRED and mapping[e] != truth[i]
    ]
    return np.asarray(out, dtype=float).reshape(-1, 2, 2)
