"""The error budget (ekfslam.analysis.error_budget): each source alone and all but it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ekfslam.analysis.error_budget import BudgetRow, ErrorBudget, error_budget, map_error
from ekfslam.analysis.lab_checks import check_sources_above
from ekfslam.core.noise import NoiseConfig
from ekfslam.sim.scenarios import realistic, realistic_noise

NOTEBOOKS = Path(__file__).resolve().parents[2] / "notebooks"


def test_a_two_source_budget_is_made_of_the_runs_it_names():
    budget = error_budget("square", sources=("tag placement", "range scale"))
    tags, scale = budget.row("tag placement"), budget.row("range scale")
    # with two sources "all but one" is "the other alone": the same simulation, the same number
    assert tags.all_but == scale.alone and scale.all_but == tags.alone
    assert budget.ideal == map_error(realistic("square", ()))
    assert budget.realistic == map_error(realistic("square", ("tag placement", "range scale")))
    assert budget.seeds == (1,)  # the seed's square experiment
    assert budget.ideal == pytest.approx(0.005, abs=0.002)
    # each source alone is several centimetres; together they make less than their sum
    assert tags.alone == pytest.approx(0.042, abs=0.003)
    assert scale.alone == pytest.approx(0.070, abs=0.003)
    assert budget.realistic == pytest.approx(0.073, abs=0.003)
    assert budget.realistic < tags.alone + scale.alone
    assert (tags.field, tags.value) == ("tag_position_sigma", 0.03)
    with pytest.raises(KeyError, match="no error source 'slip'"):
        budget.row("slip")


def test_every_row_replays_with_the_realistic_robots_noise():
    """The rows differ only in the robot: each replays with `realistic_noise`, the noise
    run.json gives the realistic runs, not the generic noise a run with some sources gets."""
    config = realistic("square", ("range scale",))
    assert map_error(config) == map_error(config, realistic_noise())
    assert map_error(config) != map_error(config, NoiseConfig())


def test_seeds_are_averaged_and_bad_sources_are_named():
    one, two = (error_budget("octagon", ("wheel radius",), seeds=s) for s in ((3,), (3, 4)))
    four = error_budget("octagon", ("wheel radius",), seeds=(4,))
    assert two.row("wheel radius").alone == pytest.approx(
        (one.row("wheel radius").alone + four.row("wheel radius").alone) / 2, rel=1e-12
    )
    with pytest.raises(ValueError, match="unknown error sources"):
        error_budget("square", ("gremlins",))
    with pytest.raises(ValueError, match="at least one seed"):
        error_budget("square", ("wheel radius",), seeds=())


def _made_up_budget():
    rows = (
        BudgetRow("tag placement", "tag_position_sigma", 0.03, "tape", 0.034, 0.138),
        BudgetRow("wheel slip", "slip_fraction", 0.02, "floor", 0.006, 0.143),
        BudgetRow("motor lag", "motor_lag", 0.3, "motors", 0.061, 0.090),
    )
    return ErrorBudget("square", (1,), 0.005, 0.124, rows)


def test_the_prediction_check_names_each_source_on_the_wrong_side(capsys):
    budget = _made_up_budget()
    assert check_sources_above(None, budget) is False
    assert "Not answered yet" in capsys.readouterr().out
    assert check_sources_above({"tag placement", "motor lag"}, budget) is True
    assert capsys.readouterr().out.startswith("Right: on the square")
    # the usual wrong answer: slip must cost a lot, since a robot that slips gets lost
    assert check_sources_above({"tag placement", "wheel slip", "motor lag"}, budget) is False
    assert capsys.readouterr().out == (
        "Not quite: you put wheel slip above 1 cm; alone it costs 6 mm on the square.\n"
    )
    assert check_sources_above({"tag placement"}, budget) is False
    assert "you put motor lag below 1 cm; alone it costs 61 mm" in capsys.readouterr().out
    assert check_sources_above({"gremlins"}, budget) is False
    assert "['gremlins'] are not sources of the table" in capsys.readouterr().out


@pytest.mark.slow
def test_notebook_07s_answer_is_right_on_the_budget_it_shows(capsys):
    """The solution's prediction, run against the budget notebook 07 computes (seeds 1-4)."""
    cells = json.loads((NOTEBOOKS.parent / "solutions" / "07-alignment.ipynb").read_text())["cells"]
    answer = "".join(next(c["source"] for c in cells if c["id"] == "07-r5"))
    namespace: dict = {}
    exec(answer, namespace)
    budget = error_budget("square", seeds=(1, 2, 3, 4))
    assert check_sources_above(namespace["over_1cm"], budget) is True
    assert budget.realistic == pytest.approx(0.132, abs=0.003)
    assert max(r.alone for r in budget.rows if r.source.startswith("wheel")) < 0.01
