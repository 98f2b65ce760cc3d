"""``python -m studies budget``: the error budget's table, JSON and figure from the command line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from studies_cli import run_studies

from ekfslam.analysis.error_budget import error_budget


def test_budget_prints_the_table_and_json_of_the_analysis(tmp_path: Path):
    plot = tmp_path / "figs" / "budget.png"
    out = run_studies("budget", "octagon", "--seeds", "3", "--json", "--plot", str(plot))
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    same = error_budget("octagon", seeds=(3,))  # what the command computes, in this process
    assert data["seeds"] == [3] and data["trajectory"] == "octagon"
    assert data["realistic_by_seed"] == [pytest.approx(same.realistic, rel=1e-9)]
    assert data["realistic"] == pytest.approx(same.realistic, rel=1e-9)
    assert [r["source"] for r in data["rows"]] == [r.source for r in same.rows]
    for row, expected in zip(data["rows"], same.rows, strict=True):
        assert row["alone"] == pytest.approx(expected.alone, rel=1e-9)
        assert row["all_but"] == pytest.approx(expected.all_but, rel=1e-9)
    assert data["seed_report"] == 0.130 and data["noise"]["sigma_bearing"] > 0.15
    assert data["plot"] == str(plot) and plot.stat().st_size > 10_000
    text = run_studies("budget", "octagon", "--seeds", "3")
    lines = text.stdout.splitlines()
    assert lines[0] == "octagon (seeds 3): map error, mm"
    assert lines[-2].split()[-1] == f"{1000 * same.realistic:.0f}"
    assert lines[-1].split() == ["the", "seed's", "robot", "130"]


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["circle"], "argument trajectory: invalid choice: 'circle'"),
        (["square", "--seeds", "2", "2"], "argument --seeds: seed 2 is given twice"),
        (["square", "--seeds", "-1"], "argument --seeds: must be >= 0, got -1"),
        (["square", "--plot", "budget.txt"], "argument --plot: the file must end in .png"),
        ([], "the following arguments are required: trajectory"),
    ],
)
def test_budget_refuses_a_bad_option_in_one_line(argv: list[str], says: str):
    out = run_studies("budget", *argv)
    assert out.returncode == 2 and out.stdout == ""
    assert len(out.stderr.splitlines()) == 1 and says in out.stderr, out.stderr
