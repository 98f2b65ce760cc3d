"""``python -m studies score-mrclam``: the README's MRCLAM tables, with and without the barcodes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from studies_cli import run_studies, studies_main

from ekfslam.logs.mrclam import load as mrclam
from studies.cli import score_mrclam


def test_score_mrclam_without_the_data_fails_cleanly(tmp_path: Path, monkeypatch, capsys):
    """Regression: the README's MRCLAM one-liner gave a traceback without the data."""
    # nowhere to find it: one line on stderr that says how to fetch it, exit 2
    monkeypatch.setenv("EKFSLAM_SHARED_DATA", str(tmp_path / "shared"))
    monkeypatch.setenv("EKFSLAM_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(
        mrclam, "__file__", str(tmp_path / "a" / "ekfslam" / "logs" / "mrclam" / "load.py")
    )
    assert studies_main(["score-mrclam", "7"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.endswith("dataset 7 not found; run `python -m ekfslam fetch mrclam 7`")


@pytest.mark.shared_data
def test_score_mrclam_prints_the_readmes_table(mrclam7: Path, monkeypatch):
    monkeypatch.setenv("EKFSLAM_SHARED_DATA", str(mrclam7.parents[1]))
    out = run_studies("score-mrclam", "7")
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].startswith("| robot | landmarks | mean error aligned (m) |")
    robots = [line.split("|")[1].strip() for line in lines[2:]]
    assert robots == ["1", "2", "3", "4", "5", "average"]


@pytest.mark.slow
@pytest.mark.shared_data
def test_score_mrclam_with_the_barcodes_hidden_reports_every_robot(mrclam7: Path, monkeypatch):
    monkeypatch.setenv("EKFSLAM_SHARED_DATA", str(mrclam7.parents[1]))
    out = run_studies("score-mrclam", "7", "--association", "nn", "jcbb", "--json")
    assert out.returncode == 0, out.stderr
    rows = json.loads(out.stdout)["rows"]
    assert [(r["robot"], r["method"]) for r in rows] == [
        (robot, m) for robot in (1, 2, 3, 4, 5) for m in ("nn", "jcbb")
    ]
    for r in rows:
        assert r["ratio"] == pytest.approx(r["aligned_error"] / r["known_error"])
        assert r["ratio_same_noise"] == pytest.approx(r["aligned_error"] / r["known_same_noise"])
        assert r["correct"] + r["wrong"] + r["missed"] > 1000
        assert 0.4 < r["correct_fraction"] < 1.0  # the close pairs: far from the seed's 100%
    for r in (r for r in rows if r["method"] == "jcbb"):  # 2026-12-01: 73-82%, 1.1-2.5x
        assert r["correct_fraction"] > 0.7 and r["ratio_same_noise"] < 3.0, r


@pytest.mark.parametrize(
    ("flag", "mapped"),
    [((), True), (("--map-noise", "mrclam"), True), (("--map-noise", "none"), False)],
)
def test_score_mrclam_maps_with_a_second_filter_unless_told_not_to(
    flag, mapped, monkeypatch, tmp_path: Path, capsys
):
    """--map-noise reaches `association_robots` (the work itself is stubbed: no data needed)."""
    seen = {}

    def robots(folder, methods, **kw):
        seen.update(kw)
        return []

    monkeypatch.setattr(score_mrclam, "mrclam_folder", lambda dataset: tmp_path)
    monkeypatch.setattr(score_mrclam, "association_robots", robots)
    monkeypatch.setattr(score_mrclam, "association_table", lambda rows: "table")
    assert studies_main(["score-mrclam", "7", "--association", "jcbb", *flag]) == 0
    assert seen["mapped"] is mapped
    assert seen["time_shared"] is None  # the source's: one error per image on MRCLAM
    assert capsys.readouterr().out == "table\n"


@pytest.mark.parametrize(("flag", "shared"), [("shared", True), ("independent", False)])
def test_score_mrclam_time_error_reaches_the_replays(
    flag, shared, monkeypatch, tmp_path: Path, capsys
):
    seen = {}
    monkeypatch.setattr(score_mrclam, "mrclam_folder", lambda dataset: tmp_path)
    monkeypatch.setattr(score_mrclam, "association_robots", lambda f, m, **kw: seen.update(kw))
    monkeypatch.setattr(score_mrclam, "association_table", lambda rows: "table")
    assert studies_main(["score-mrclam", "7", "--association", "jcbb", "--time-error", flag]) == 0
    assert seen["time_shared"] is shared


def test_score_mrclam_refuses_passes_without_association_in_one_line():
    bad = run_studies("score-mrclam", "7", "--passes", "2")
    assert bad.returncode == 2
    assert bad.stderr.count("\n") == 1 and "--passes" in bad.stderr, bad.stderr
