"""The error budget's table and figure (ekfslam.viz.budget)."""

from __future__ import annotations

import dataclasses

from ekfslam.analysis.error_budget import BudgetRow, ErrorBudget
from ekfslam.viz.budget import budget_figure, budget_markdown, budget_text


def _budget(trajectory, k):
    rows = (
        BudgetRow("tag placement", "tag_position_sigma", 0.03, "tape", 0.035 + k, 0.080),
        BudgetRow("range scale", "range_scale", 1.05, "focal length", 0.040, 0.056 + k),
    )
    return ErrorBudget(trajectory, (1, 2), 0.005, 0.085 + k, rows)


def test_the_table_gives_each_source_alone_and_all_but_in_mm_with_the_seeds_row():
    budgets = [_budget("square", 0.0), _budget("octagon", 0.01)]
    md = budget_markdown(budgets, {"square": 0.153, "octagon": 0.130}).splitlines()
    assert md[0] == (
        "| error source | value | square: alone | square: all but | octagon: alone "
        "| octagon: all but |"
    )
    assert md[2] == "| tag placement | tag_position_sigma = 0.03 | 35 | 80 | 45 | 80 |"
    assert md[3] == "| range scale | range_scale = 1.05 | 40 | 56 | 40 | 66 |"
    assert md[5] == "| all (realistic robot) | | 85 |  | 95 |  |"
    assert md[6] == "| the seed's real robot | | 153 |  | 130 |  |"
    assert len(budget_markdown(budgets, {}).splitlines()) == 6  # no seed row without its numbers
    text = budget_text(budgets[0]).splitlines()
    assert text[0] == "square (seeds 1, 2): map error, mm"
    assert text[2].split() == ["tag", "placement", "35", "80"]
    assert len(text) == 6  # one seed's errors are not given: no spread line
    spread = dataclasses.replace(budgets[0], realistic_by_seed=(0.0904, 0.0796, 0.120))
    assert budget_text(spread).splitlines()[-1].split() == [
        "by",
        "seed",
        "min",
        "80,",
        "median",
        "90,",
        "max",
        "120",
    ]


def test_the_figure_has_a_panel_per_path_with_the_sources_on_top_first():
    fig = budget_figure([_budget("square", 0.0), _budget("octagon", 0.01)], {"square": 0.153})
    left, right = fig.axes
    assert [t.get_text() for t in left.get_yticklabels()] == ["tag placement", "range scale"]
    assert left.get_ylim()[0] > left.get_ylim()[1]  # inverted: the first source on top
    assert left.get_title() == "square: ideal robot 0.5 cm"
    assert len(left.patches) == 4 and len(left.lines) == 3  # realistic, seed, zero
    assert len(right.lines) == 2  # no seed's number given for the octagon
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert (
        "the seed's real robot" in labels
        and min(t.get_fontsize() for t in left.get_yticklabels()) >= 11
    )
