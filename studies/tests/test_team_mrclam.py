"""``python -m studies team-mrclam``: each robot alone and the team in one map, per dataset."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from studies_cli import studies_main

from ekfslam.logs.mrclam import load as mrclam


def test_without_the_data_it_says_how_to_fetch_it(tmp_path: Path, monkeypatch, capsys):
    monkeypatch.setenv("EKFSLAM_SHARED_DATA", str(tmp_path / "shared"))
    monkeypatch.setenv("EKFSLAM_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(
        mrclam, "__file__", str(tmp_path / "a" / "ekfslam" / "logs" / "mrclam" / "load.py")
    )
    assert studies_main(["team-mrclam"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "fetch mrclam 7" in err


@pytest.mark.shared_data
def test_dataset_7_maps_better_together(mrclam7: Path, capsys):
    assert studies_main(["team-mrclam", str(mrclam7), "--json"]) == 0
    (row,) = json.loads(capsys.readouterr().out)
    assert row["dataset"] == 7 and [r["robot"] for r in row["robots"]] == [1, 2, 3, 4, 5]
    assert row["joint_map"] < row["alone_best"] < row["alone_mean"]
    assert row["joint_map"] <= row["joint_map_no_robot_sightings"]
    assert all(r["joint_ate"] < r["alone_ate"] for r in row["robots"])
    assert all(r["entry"] == "start" for r in row["robots"])
    # the ids hidden: still a map of every landmark, worse than with the ids, timed
    assert row["joint_map"] < row["joint_map_hidden"] < 0.1  # measured 0.028 m
    assert row["hidden_seconds"] > 0 and row["joint_seconds"] > 0
    capsys.readouterr()
    assert studies_main(["team-mrclam", str(mrclam7)]) == 0
    table = capsys.readouterr().out
    assert "| 7 | 5 |" in table and "joint map (m)" in table
    assert "joint, ids hidden (m)" in table and "median of 3" in table
