"""``run`` says whether the replay agrees with its data: one line, the JSON, a warning on stderr."""

from __future__ import annotations

import json
from pathlib import Path

from ekfslam_cli import run_ekfslam

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
