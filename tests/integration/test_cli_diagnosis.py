"""``run`` says whether the replay agrees with its data: one line, the JSON, a warning on stderr."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
from ekfslam_cli import run_ekfslam

from ekfslam.logs.runlog import Controls, read_run, write_run

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


def test_run_says_the_verdict_on_stdout_in_the_json_and_warns_on_stderr(mrclam7) -> None:
    small = ["--sigma-x", "5e-5", "--sigma-y", "5e-5", "--sigma-theta", "5e-4"]
    small += ["--sigma-range", "3e-3", "--sigma-bearing", "1e-4"]
    out = run_ekfslam("run", str(mrclam7), "--robot", "1", *small, "--json")
    assert out.returncode == 0
    assert json.loads(out.stdout)["diagnosis"]["verdict"] == "lost"
    assert "warning: lost: 100% of sightings rejected after t = 1 s" in out.stderr
    assert out.stderr.rstrip().endswith("R or Q is too small for this log; try --noise fit")
    text = run_ekfslam("run", str(RUNS / "square-2laps"))
    assert "diagnosis: ok: 0% of 482 sightings" in text.stdout
    assert "warning" not in text.stderr


def test_by_default_a_log_the_documented_noise_loses_is_replayed_with_r_rescued(tmp_path) -> None:
    """The square with its odometry held 0.5 s at a time: the documented noise is lost, the
    default replays with R x 4 (the most likely) and says so; --noise documented does not."""
    run = read_run(RUNS / "square-2laps")
    c = run.controls
    piece = np.floor((c.t - c.t[0]) / 0.5)
    first = np.concatenate([[True], piece[1:] != piece[:-1]])
    coarse = dataclasses.replace(run, controls=Controls(c.t[first], c.kind, c.values[first]))
    write_run(coarse, tmp_path / "coarse")
    out = run_ekfslam("run", str(tmp_path / "coarse"))
    assert out.returncode == 0 and "warning" not in out.stderr
    assert "noise: the documented noise was lost (" in out.stdout
    assert "replayed with R x 4, the most likely of x1 lost" in out.stdout
    assert "diagnosis: ok" in out.stdout
    doc = json.loads(run_ekfslam("run", str(tmp_path / "coarse"), "--json").stdout)
    assert doc["noise_rescue"]["scale"] == 4.0 and doc["diagnosis"]["verdict"] == "ok"
    exact = run_ekfslam("run", str(tmp_path / "coarse"), "--noise", "documented", "--json")
    assert json.loads(exact.stdout)["diagnosis"]["verdict"] == "lost"
    assert "noise_rescue" not in json.loads(exact.stdout)
    assert "warning: lost:" in exact.stderr


def test_run_recover_relocalises_a_robot_whose_odometry_dropped_out(tmp_path) -> None:
    run = read_run(RUNS / "octagon-2laps")
    c = run.controls
    still = np.where(((c.t >= 35.0) & (c.t < 37.0))[:, None], 0.0, c.values)
    write_run(dataclasses.replace(run, controls=Controls(c.t, c.kind, still)), tmp_path / "drop")
    args = ["run", str(tmp_path / "drop"), "--noise", "documented", "--json"]
    lost = json.loads(run_ekfslam(*args).stdout)
    found = json.loads(run_ekfslam(*args, "--recover").stdout)
    assert lost["diagnosis"]["verdict"] == "lost" and lost["alignment"]["mean_error"] > 0.15
    assert found["diagnosis"]["verdict"] == "ok" and found["alignment"]["mean_error"] < 0.01
    assert len(found["diagnosis"]["recoveries"]) == 1
    refused = run_ekfslam("run", str(RUNS / "square-2laps"), "--recover", "--association", "nn")
    assert refused.returncode == 2 and "argument --recover: needs the ids known" in refused.stderr
