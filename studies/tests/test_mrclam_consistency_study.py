"""The consistency study on MRCLAM: the grid that chose `MRCLAM_CONSISTENT_NOISE`, and
``python -m studies consistency mrclam`` (its JSON, its table, its refusal)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from studies_cli import run_studies

from ekfslam.analysis.mrclam_consistency import INTERVAL, mrclam_consistency
from ekfslam.logs.mrclam.defaults import MRCLAM_CONSISTENT_NOISE, MRCLAM_NOISE
from studies.mrclam_consistency import tune_for_consistency


def cli(*args: str, env: dict | None = None):
    """``python -m studies consistency ARGS``."""
    return run_studies("consistency", *args, env=env)


@pytest.fixture(scope="module")
def measured(mrclam7: Path) -> dict:
    """The robots the tests below compare with, replayed by the package's study."""
    return {
        "map": mrclam_consistency(mrclam7, "map", robots=(2,)),
        "consistent": mrclam_consistency(mrclam7, "consistent", robots=(2, 3, 5)),
    }


@pytest.mark.slow
def test_tuning_ranks_by_distance_after_the_map_targets(measured: dict, mrclam7: Path) -> None:
    rows = tune_for_consistency(mrclam7, {"sigma_x": (0.01, 0.05)}, MRCLAM_CONSISTENT_NOISE, (2, 3))
    assert len(rows) == 2
    keys = [(not r.meets(), r.distance) for r in rows]
    assert keys == sorted(keys)
    row = next(r for r in rows if r.noise["sigma_x"] == 0.05)  # MRCLAM_CONSISTENT_NOISE itself
    study = measured["consistent"]
    assert row.nees == tuple(study.get(robot, "standard").mean for robot in (2, 3))
    assert row.distance == pytest.approx(np.mean(np.abs(np.log(np.array(row.nees) / 3))))


@pytest.mark.slow
def test_tuning_for_consistency_is_the_same_on_two_processes(mrclam7: Path) -> None:
    grid = {"sigma_x": (0.02, 0.05), "sigma_theta": (0.05, 0.1)}
    one = tune_for_consistency(mrclam7, grid, MRCLAM_CONSISTENT_NOISE, (2,), jobs=1)
    two = tune_for_consistency(mrclam7, grid, MRCLAM_CONSISTENT_NOISE, (2,), jobs=2)
    assert len(one) == 4
    assert one == two  # every field, exactly: each point replays the same robot the same way


# -------------------------------------------------------------------------------- command line
@pytest.mark.slow
def test_cli_json_keys_values_and_plot(measured: dict, mrclam7: Path, tmp_path: Path) -> None:
    plot = tmp_path / "nees.png"
    done = cli("mrclam", str(mrclam7), "--robots", "2", "--json", "--plot", str(plot))
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    assert {"robots", "average", "interval", "ideal", "noise_name", "noise", "plot"} <= set(out)
    assert out["interval"] == pytest.approx(INTERVAL) and out["ideal"] == 3
    assert out["noise_name"] == "map" and out["noise"]["sigma_x"] == MRCLAM_NOISE.sigma_x
    row = out["robots"]["2"]["fej"]
    assert set(row) == {
        "mean",
        "median",
        "fraction_in_interval",
        "heading_mean",
        "aligned_error",
        "rejected",
        "rows",
    }
    assert row["mean"] == pytest.approx(measured["map"].get(2, "fej").mean, rel=1e-9)
    assert out["average"]["standard"]["mean"] == pytest.approx(
        out["robots"]["2"]["standard"]["mean"]
    )
    assert plot.stat().st_size > 10_000 and plot.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_cli_finds_dataset_7_and_prints_the_table(measured: dict, mrclam7: Path) -> None:
    env = {"EKFSLAM_SHARED_DATA": str(mrclam7.parents[1])}
    done = cli(
        "mrclam", "--noise", "consistent", "--robots", "5", "--linearization", "fej", env=env
    )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert "noise 'consistent'" in lines[0] and "fej mean" in lines[1]
    assert "standard" not in lines[1]
    row = next(line for line in lines if line.startswith("5 "))
    assert float(row.split()[1]) == pytest.approx(
        measured["consistent"].get(5, "fej").mean, abs=0.05
    )


def test_cli_bad_dataset_is_one_line_and_exit_2(tmp_path: Path) -> None:
    done = cli("mrclam", str(tmp_path / "nowhere"), "--json")
    assert done.returncode == 2
    # refused while parsing, before any work: the parser's one line names the argument
    assert done.stderr.startswith("python -m studies consistency mrclam: error: argument DATASET")
    assert len(done.stderr.strip().splitlines()) == 1
    assert "nowhere" in done.stderr and "Traceback" not in done.stderr
