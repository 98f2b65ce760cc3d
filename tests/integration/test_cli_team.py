"""``python -m ekfslam run DATASET --robots ...`` as a user types it: the joint map's row and
each robot's line, the JSON a script reads, the figure, and one-line refusals."""

from __future__ import annotations

import json

import pytest
from ekfslam_cli import run_ekfslam

pytestmark = pytest.mark.shared_data


def test_the_team_json_carries_the_joint_map_and_every_robot(mrclam7, tmp_path):
    figure = tmp_path / "team.png"
    done = run_ekfslam("run", str(mrclam7), "--robots", "all", "--json", "--plot", str(figure))
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert out["alignment"]["mean_error"] < 0.025  # measured 0.013 m; alone 0.027-0.086 m
    assert out["alignment"]["landmarks_matched"] == 15
    assert sorted(out["robots"]) == ["1", "2", "3", "4", "5"]
    for robot in out["robots"].values():
        assert robot["entry"]["how"] == "start"
        assert 0.0 < robot["trajectory"]["ate_rmse"] < 0.3  # alone: 0.26-0.90 m
        assert robot["sightings"]["landmarks"]["accepted"] > 1000
        assert robot["sightings"]["robots"]["accepted"] > 300
        diagnosis = robot["diagnosis"]  # a single replay's, per robot
        assert diagnosis["verdict"] == "ok" and diagnosis["warning"] is None
        assert diagnosis["sightings"] > 1500  # measured 1821-4420
        assert diagnosis["outlier_share"] < 0.1  # measured 0.03-0.07
        assert 0.8 < diagnosis["nis"]["mean_capped"] < 1.98  # measured 1.05-1.52
        assert diagnosis["line"].startswith("diagnosis: ok: ")
        assert not diagnosis["lost_at_end"]
    assert out["seconds"] > 0 and out["loaded"]["robot_sightings"]["kept"] > 4000
    assert figure.stat().st_size > 50_000 and figure.read_bytes()[:4] == b"\x89PNG"


def test_the_team_table_as_printed(mrclam7):
    done = run_ekfslam("run", str(mrclam7), "--robots", "3", "1")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].split()[:2] == ["Map", "x0"] and lines[1].startswith("mrclam7-team")
    robots = [line for line in lines if line.startswith("robot ")]
    assert [line.split(":")[0] for line in robots] == ["robot 1", "robot 3"]
    assert all("trajectory error 0." in line for line in robots)
    diagnoses = [line for line in lines if line.startswith("  diagnosis: ")]
    assert len(diagnoses) == 2 and all(" sightings beyond the χ² 99% bound" in d for d in diagnoses)
    assert lines.index(diagnoses[0]) == lines.index(robots[0]) + 1  # under its robot
    assert lines[-1].startswith("2 robots in ")


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--robots", "2", "2"], "robot 2 is named twice"),
        (["--robots", "all", "3"], "give all, or robot numbers, not both"),
        (["--robots", "all", "--robot", "2"], "give --robot N (one robot) or --robots"),
        (["--robots", "all", "--association", "mht"], "--association mht is not available"),
        (["--robots", "all", "--noise", "fit"], "--noise is not available with --robots"),
        (["--robots", "6"], "MRCLAM robots are 1, 2, 3, 4, 5; got '6'"),
    ],
)
def test_bad_team_choices_are_refused_in_one_line(mrclam7, extra, says):
    done = run_ekfslam("run", str(mrclam7), *extra)
    assert done.returncode != 0
    assert says in done.stderr and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1
    assert done.stdout == ""


def test_a_team_needs_a_mrclam_dataset(tmp_path):
    done = run_ekfslam("run", "data/runs/octagon-2laps", "--robots", "all")
    assert done.returncode != 0 and "needs a MRCLAM dataset folder" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_team_with_hidden_ids_says_how_its_sightings_were_paired(mrclam7):
    done = run_ekfslam("run", str(mrclam7), "--robots", "1", "2", "--hide-ids", "--json")
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    block = out["association"]
    assert block["method"] == "jcbb" and block["match"] == "mapping"  # --hide-ids: jcbb
    assert "barcodes known" in block["barcodes"]
    assert block["correct"] > 3000 and block["landmarks_mapped"] >= 15  # measured 4706, 22
    assert block["correct"] + block["wrong"] + block["missed"] <= sum(
        r["diagnosis"]["sightings"] + 100 for r in out["robots"].values()
    )
    assert block["counts"]["associated"] > 5000 and block["time_error"]["form"] == "shared"
    assert 0.0 < out["alignment"]["mean_error"] < 0.5  # measured 0.234 m: two robots, DS7
    assert out["alignment"]["landmarks_matched"] >= 10
    assert all(r["entry"]["how"] == "start" for r in out["robots"].values())
    text = run_ekfslam("run", str(mrclam7), "--robots", "1", "2", "--association", "nn")
    assert text.returncode == 0, text.stderr
    assert "landmark ids hidden (nn; the robots' barcodes known): " in text.stdout
