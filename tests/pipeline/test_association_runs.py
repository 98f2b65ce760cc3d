"""The seed's two runs replayed with their ids hidden: nn and jcbb against known (issue 16)."""

from __future__ import annotations

from pathlib import Path

import pytest

from ekfslam.analysis import association
from ekfslam.analysis.evaluation import summarize
from ekfslam.core.association import AssociationConfig
from ekfslam.logs.runlog import read_run
from ekfslam.pipeline import replay

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


@pytest.mark.parametrize("name", ["square-2laps", "octagon-2laps"])
@pytest.mark.parametrize("method", ["nn", "jcbb"])
def test_hidden_ids_associate_and_map_as_well_as_known(name: str, method: str):
    run = read_run(RUNS / name)
    known = summarize(run, replay(run)).alignment.mean_error
    result, found = association.score(
        run, replay(run, association=AssociationConfig(method=method))
    )
    assert found.correct_fraction >= 0.99
    assert not found.duplicates and found.wrong == 0
    assert sorted(found.mapping.values()) == sorted(run.meta.tag_map)
    error = summarize(run, result).alignment.mean_error
    assert error <= max(1.2 * known, known + 0.01)


def test_known_is_the_replay_without_association():
    run = read_run(RUNS / "octagon-2laps")
    plain, chosen = replay(run), replay(run, association=AssociationConfig(method="known"))
    assert chosen.association is None
    assert (plain.mu == chosen.mu).all() and (plain.Sigma == chosen.Sigma).all()
