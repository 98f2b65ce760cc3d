"""The error budget (ekfslam.analysis.error_budget): each source alone and all but it."""

from __future__ import annotations

import pytest

from ekfslam.analysis.error_budget import error_budget, map_error
from ekfslam.sim.scenarios import realistic


def test_a_two_source_budget_is_made_of_the_runs_it_names():
    budget = error_budget("square", sources=("tag placement", "range scale"))
    tags, scale = budget.row("tag placement"), budget.row("range scale")
    # with two sources "all but one" is "the other alone": the same simulation, the same number
    assert tags.all_but == scale.alone and scale.all_but == tags.alone
    assert budget.ideal == map_error(realistic("square", ()))
    assert budget.realistic == map_error(realistic("square", ("tag placement", "range scale")))
    assert budget.seeds == (1,)  # the seed's square experiment
    assert budget.ideal == pytest.approx(0.005, abs=0.002)
    # each source alone is several centimetres; together they add about in quadrature
    assert tags.alone == pytest.approx(0.040, abs=0.005)
    assert scale.alone == pytest.approx(0.041, abs=0.005)
    assert budget.realistic == pytest.approx(0.058, abs=0.01)
    assert budget.realistic < tags.alone + scale.alone
    assert (tags.field, tags.value) == ("tag_position_sigma", 0.03)
    with pytest.raises(KeyError, match="no error source 'slip'"):
        budget.row("slip")


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
