"""Tests of ekfslam.viz.tables: the seed's Table 1 as text (command line, panel) and Markdown."""

from __future__ import annotations

from dataclasses import replace

import pytest

from ekfslam.analysis.evaluation import SEED_TABLE1, summarize
from ekfslam.errors import EkfSlamError
from ekfslam.viz.tables import PANEL, table1_lines, table1_markdown


def test_table1_markdown_puts_each_run_beside_the_seed(square, square_result) -> None:
    summary = summarize(square, square_result)
    seed = {"square": (-0.02, 0.056, 0.142, 0.153)}
    table = table1_markdown({"square": summary}, seed).splitlines()
    assert len(table) == 4
    a = summary.alignment
    assert table[2].startswith("| square, this simulation")
    assert f"{a.x0:.3f}" in table[2] and f"{a.mean_error:.3f}" in table[2]
    assert table[3] == "| square, seed report (real robot) | -0.020 | 0.056 | 0.142 | 0.153 |"
    with pytest.raises(EkfSlamError, match="no alignment"):
        table1_markdown({"square": replace(summary, alignment=None)}, seed)


def test_table1_text_in_the_command_line_and_panel_layouts(square, square_result) -> None:
    summary = summarize(square, square_result)
    a = summary.alignment
    x0, y0, t0, err = SEED_TABLE1["square"]
    assert table1_lines(summary, SEED_TABLE1["square"]) == [
        f"{'Trajectory':<22}{'x0':>9}{'y0':>9}{'theta0':>9}{'Average Error':>15}",
        f"{summary.name:<22}{a.x0:>9.3f}{a.y0:>9.3f}{a.theta0:>9.3f}{a.mean_error:>15.3f}",
        f"{'  seed report (real)':<22}{x0:>9.3f}{y0:>9.3f}{t0:>9.3f}{err:>15.3f}",
    ]
    panel = table1_lines(summary, SEED_TABLE1["square"], layout=PANEL, extra=("avg NIS", "1.23"))
    assert panel == [
        f"{'Trajectory':<16}{'x0':>8}{'y0':>8}{'theta0':>8}{'Avg error':>11}{'avg NIS':>9}",
        f"{summary.name:<16}{a.x0:>8.3f}{a.y0:>8.3f}{a.theta0:>8.3f}{a.mean_error:>11.3f}{'1.23':>9}",
        f"{'seed (real)':<16}{x0:>8.3f}{y0:>8.3f}{t0:>8.3f}{err:>11.3f}",
    ]
    blind = replace(summary, alignment=None, alignment_note="the run has no known tag map")
    assert (
        table1_lines(blind)[1]
        == f"{summary.name:<22}  (no alignment: the run has no known tag map)"
    )
