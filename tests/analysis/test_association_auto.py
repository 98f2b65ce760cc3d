"""Tests of ekfslam.analysis.association_auto: jcbb first, escalated only where its diagnosis
says the map is not to be trusted (issue 39)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from ekfslam import pipeline
from ekfslam.analysis import association as assoc
from ekfslam.analysis import association_auto as auto
from ekfslam.analysis.evaluation import summarize
from ekfslam.logs.runlog import read_run

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


@pytest.fixture(scope="module")
def square():
    return read_run(RUNS / "square-2laps")


def test_a_map_jcbb_associates_right_is_kept_without_escalating(square) -> None:
    chosen = auto.replay_auto(square)
    assert (chosen.strategy, chosen.escalated, len(chosen.tried)) == (auto.FIRST, False, 1)
    assert chosen.result.association.method == "jcbb"
    _, found = assoc.score(square, chosen.result)
    assert found.correct_fraction == 1.0
    assert chosen.line() == "association: auto used jcbb (its diagnosis is ok)"
    assert chosen.as_dict()["tried"][0]["verdict"] == "ok"


class _Replays:
    """`pipeline.replay` replaced: the real replay, its diagnosis's verdict set by method."""

    def __init__(self, verdicts: dict[str, str]) -> None:
        self.verdicts, self.methods, self.real = verdicts, [], pipeline.replay

    def __call__(self, run, *args, association=None, **kwargs):
        hidden, association = association, association.association  # a HiddenIds
        self.methods.append((association.method, association.hypotheses, hidden.passes))
        result = self.real(run, *args, association=hidden, **kwargs)
        verdict = self.verdicts[association.method]
        reasons = () if verdict == "ok" else (f"{association.method} said {verdict}",)
        d = dataclasses.replace(result.diagnosis, verdict=verdict, reasons=reasons)
        return dataclasses.replace(result, diagnosis=d)


def test_a_map_not_to_be_trusted_is_replayed_by_the_escalation_and_says_why(
    square, monkeypatch
) -> None:
    fake = _Replays({"jcbb": "suspect", "mht": "ok"})
    monkeypatch.setattr(pipeline, "replay", fake)
    chosen = auto.replay_auto(square, escalation=auto.Strategy("mht", hypotheses=2))
    assert fake.methods == [("jcbb", 8, 1), ("mht", 2, 1)]
    assert chosen.escalated and chosen.strategy == auto.Strategy("mht", hypotheses=2)
    assert chosen.result.association.method == "mht"
    assert chosen.line().startswith(
        "association: auto used mht --hypotheses 2, ok: jcbb was suspect (jcbb said suspect); "
    )
    assert chosen.seconds == pytest.approx(sum(t.seconds for t in chosen.tried))


def test_an_escalation_that_diagnoses_worse_is_not_kept(square, monkeypatch) -> None:
    fake = _Replays({"jcbb": "suspect"})
    calls = iter(["suspect", "lost"])

    def replay(run, *args, association=None, **kwargs):
        fake.verdicts["jcbb"] = next(calls)
        return fake(run, *args, association=association, **kwargs)

    monkeypatch.setattr(pipeline, "replay", replay)
    chosen = auto.replay_auto(square, escalation=auto.Strategy("jcbb", passes=2))
    assert fake.methods == [("jcbb", 8, 1), ("jcbb", 8, 2)]
    assert chosen.strategy == auto.FIRST and chosen.escalated
    assert chosen.line() == (
        "association: auto kept jcbb: jcbb was suspect (jcbb said suspect), and "
        "jcbb --passes 2 was lost, no better"
    )


@pytest.mark.slow
def test_on_dataset_1_robot_5_jcbb_is_suspect_and_the_escalation_maps_within_target(
    data_missing,
) -> None:
    """2026-12-07: jcbb maps Dataset 1 robot 5 at 0.320 m (4x known's 0.081 m), suspect (3
    landmarks founded late); auto escalates and maps it within 1.5x known + 1 cm."""
    from ekfslam.analysis.mrclam_tuning import load_robot
    from ekfslam.errors import InputError
    from ekfslam.logs.mrclam.load import find_dataset

    try:
        run = load_robot(str(find_dataset(1)), 5)
    except InputError:
        data_missing("MRCLAM Dataset 1 is not here: `python -m ekfslam fetch mrclam 1`")
    chosen = auto.replay_auto(run)
    assert chosen.tried[0].verdict == "suspect" and chosen.escalated
    assert chosen.strategy == auto.ESCALATION
    scored, _ = assoc.score(run, chosen.result)
    assert summarize(run, scored).alignment.mean_error <= 1.5 * 0.081 + 0.01
