"""``python -m studies consistency nees|association``: the issues' keys, the plots, the refusals."""

from __future__ import annotations

import json

import pytest
from studies_cli import run_studies

from ekfslam.analysis.consistency import chi2_band
from ekfslam.core.filter.config import FilterCounts
from studies.cli.consistency import counts_line

cli = run_studies


# ------------------------------------------------------------------------------ command line
@pytest.mark.slow
def test_cli_prints_the_issues_keys_and_draws_the_plot(tmp_path):
    plot = tmp_path / "c.png"
    out = cli(
        "consistency",
        "nees",
        "--runs",
        "2",
        "--trajectory",
        "square",
        "--linearization",
        "fej",
        "--json",
        "--plot",
        str(plot),
    )
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    assert d["linearization"] == "fej" and d["runs"] == 2
    for key in ("nees_pose", "nis"):
        assert set(d[key]) >= {"mean", "fraction_in_band"}
        assert 0.0 <= d[key]["fraction_in_band"] <= 1.0
    assert d["band"] == pytest.approx(list(chi2_band(3, 2)))
    assert plot.stat().st_size > 20_000


def test_cli_refuses_zero_runs():
    out = cli("consistency", "nees", "--runs", "0")
    assert out.returncode == 2 and "Traceback" not in out.stderr


def test_the_counts_line_puts_each_label_with_its_number():
    """Regression: "updates predictions 25740, initialised 160" ran the labels together."""
    counts = FilterCounts(
        predictions=25740, accepted=9000, rejected=12, refused=1, initialised=160, reinitialised=2
    )
    assert counts_line(counts) == (
        "over all runs: 25740 predictions; updates 9000 accepted, 12 rejected, 1 refused; "
        "landmarks 160 initialised, 2 re-initialised"
    )


def test_cli_all_compares_the_three_linearizations_on_the_same_runs():
    out = cli(
        "consistency",
        "nees",
        "--runs",
        "1",
        "--trajectory",
        "square",
        "--linearization",
        "all",
        "--json",
        "--jobs",
        "1",
    )
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    assert sorted(d) == ["fej", "invariant", "standard"]
    assert len({d[k]["updates"]["initialised"] for k in d}) == 1
    bad = cli("consistency", "nees", "--linearization", "iekf")
    assert bad.returncode == 2 and "invalid choice: 'iekf'" in bad.stderr
    assert "Traceback" not in bad.stderr


def test_cli_text_prints_the_counts_line():
    out = cli(
        "consistency", "nees", "--runs", "1", "--trajectory", "square", "--linearization", "fej"
    )
    assert out.returncode == 0, out.stderr
    last = out.stdout.strip().splitlines()[-1]
    assert last.startswith("over all runs: ") and " predictions; updates " in last
    assert "updates predictions" not in out.stdout


@pytest.mark.slow
def test_association_prints_both_methods_and_draws_the_picture(tmp_path):
    plot = tmp_path / "wrong.png"
    out = cli("consistency", "association", "--json", "--plot", str(plot))
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    assert d["nn"]["correct_fraction"] < 0.85 < 0.97 < d["jcbb"]["correct_fraction"]
    assert d["plot"] == str(plot) and plot.stat().st_size > 20_000
