"""Tests of ekfslam.analysis.evaluation: the outcome counts of a replay summary."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from ekfslam.analysis.evaluation import UPDATES_ORDER, summarize
from ekfslam.core.filter.history import Outcome
from ekfslam.core.noise import default_config, default_noise
from ekfslam.logs.runlog import read_run
from ekfslam.pipeline import replay

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


@pytest.mark.parametrize("name", ["octagon-2laps", "square-2laps"])
def test_the_outcome_counts_of_a_summary_add_up_to_the_sightings(name: str) -> None:
    run = read_run(RUNS / name)
    result = replay(run, default_noise(run), default_config(run))
    summary = summarize(run, result)
    updates = summary.as_dict()["updates"]
    assert list(updates) == [o.label for o in UPDATES_ORDER]
    assert sorted(UPDATES_ORDER) == list(Outcome)
    sightings = len(run.detections.t)
    assert sightings > 300
    assert sum(updates.values()) == sightings == len(result.history.obs_outcome)
    for o in Outcome:
        assert updates[o.label] == int(np.sum(result.history.obs_outcome == o))
    assert updates["accepted"] > 300  # numbers, not just the keys


def test_a_result_scored_against_another_runs_truth_says_so() -> None:
    """summarize(octagon, replay(square)) used to print confident errors; it now warns, naming
    both runs (another run's truth scores the map with confidence all the same)."""
    square, octagon = (read_run(RUNS / n) for n in ("square-2laps", "octagon-2laps"))
    result = replay(square)
    with pytest.warns(UserWarning, match="replay of 'square-2laps'.*'octagon-2laps'"):
        summarize(octagon, result)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        summarize(square, result)  # its own run: no warning
