"""The benchmark, run tiny: every key is there, every number finite and positive (no timings)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest

from benchmarks.__main__ import COMMANDS
from benchmarks.bench import BenchConfig, literal_twin, map_of
from benchmarks.cli import bench as bench_command
from ekfslam.core.filter.history import Outcome
from ekfslam.core.models import observation_noise
from ekfslam.errors import ConfigError, EkfSlamError


def bench(*args: str) -> int:
    """``python -m benchmarks bench ARGS`` in-process, without importing every other subcommand."""
    parser = argparse.ArgumentParser()
    bench_command.add_command(parser.add_subparsers(), "bench", COMMANDS["bench"][1])
    parsed = parser.parse_args(["bench", *args])
    return parsed.func(parsed)


def positive(x) -> bool:
    return isinstance(x, int | float) and math.isfinite(x) and x > 0


@pytest.mark.slow
def test_smoke_run_prints_the_issue_keys_and_writes_its_files(tmp_path: Path, capsys):
    out = tmp_path / "bench"
    assert COMMANDS["bench"][0] == "benchmarks.cli.bench"  # so `python -m benchmarks bench` exists
    args = ["--json", "--sizes", "2", "120", "--repeats", "3", "--out", str(out), "--no-mrclam"]
    assert bench(*args) == 0
    r = json.loads(capsys.readouterr().out)

    for run in ("octagon", "square"):
        assert positive(r["replay_ms"][run])
        assert positive(r["replay_events_per_s"][run])
        assert r["replay_events"][run] > 1000  # every prediction and observation of the run
    assert r["mrclam_replay_s"] is None and r["mrclam_note"] == "not run: --no-mrclam"
    assert all(positive(s) for s in r["startup_s"].values()) and r["startup_repeats"] == 3
    assert set(r["update_ratio_vs_literal"]) == {"2", "120"}
    assert all(positive(v) for v in r["update_ratio_vs_literal"].values())
    for impl in ("efficient", "literal"):
        for step in ("predict", "update"):
            assert all(positive(v) for v in r["cost_s"][impl][step].values())
    assert r["update_slope_between"] == [2, 120]
    assert positive(r["update_slope_100_1000"])  # 60x the landmarks cannot cost less
    assert positive(r["update_vs_floor_1000"]) and r["floor_n"] == 120
    assert positive(r["peak_mb_1000"]) and r["peak_memory_method"] == "tracemalloc"
    assert positive(r["fej_vs_standard"]["replay_octagon"])
    assert positive(r["fej_step"]["update"]) and positive(r["fej_step"]["predict"])
    assert r["machine"]["cores"] >= 1 and r["date"] and r["command"].startswith("python -m")
    assert r["association_vs_known"]["nn"] > 0 and r["association_vs_known"]["jcbb"] > 0
    assert r["association_map_size"] == 16 and "1" in r["association_step_ms"]
    assert r["loop"]["runs"] == 3 and positive(r["loop"]["us_per_step"]["ekfslam default"])
    assert 2.0 < r["loop"]["events_per_step"] < 5.0  # a prediction and 2 to 3 sightings

    table = (out / "bench.md").read_text()
    assert "| 120 |" in table and "octagon-2laps" in table
    assert "| ukfm ekf (reimplemented) |" in table and "- µs per event: the user's loop" in table
    assert "| MRCLAM Dataset 7, robot 1 (not run: --no-mrclam) | – s |" in table
    assert "| startup (whole process, median of 3) | wall time | target |" in table
    assert json.loads((out / "bench.json").read_text())["sizes"] == [2, 120]
    assert (out / "cost_vs_n.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_literal_twin_starts_in_the_same_state_and_stays_there():
    """The benchmark compares like with like: one update moves both the same way."""
    f, zs = map_of(6)
    lit = literal_twin(f)
    np.testing.assert_array_equal(lit.mu, f.mu)
    np.testing.assert_array_equal(lit.Sigma, f.Sigma)
    Q = observation_noise(0.05, 0.03)
    j, (r, phi) = zs[3]
    z = (r + 0.02, phi - 0.01)
    assert f.update(j, z, Q) == lit.update(j, z, Q) == Outcome.ACCEPTED
    f.predict((0.05, 0.01, 0.1), np.diag([1e-4, 1e-4, 1e-5]))
    lit.predict((0.05, 0.01, 0.1), np.diag([1e-4, 1e-4, 1e-5]))
    np.testing.assert_allclose(lit.mu, f.mu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lit.Sigma, f.Sigma, rtol=0, atol=1e-12)
    assert np.abs(f.Sigma[:3, 3:]).max() > 1e-6  # the map is correlated with the pose


def test_without_the_data_the_mrclam_row_says_why_and_how_to_fetch_it(tmp_path, monkeypatch):
    from benchmarks.bench import BenchConfig, bench_mrclam, default_mrclam_dir
    from benchmarks.report import markdown_table

    monkeypatch.setenv("EKFSLAM_SHARED_DATA", str(tmp_path / "shared"))
    monkeypatch.setenv("EKFSLAM_CACHE", str(tmp_path / "cache"))
    assert default_mrclam_dir() is None
    row = bench_mrclam(BenchConfig(mrclam_dir=None))
    assert row["mrclam_replay_s"] is None
    assert "not found" in row["mrclam_note"]
    assert "`python -m ekfslam fetch mrclam 7`" in row["mrclam_note"]
    # a fetched copy in the cache is found without --mrclam
    fetched = tmp_path / "cache" / "mrclam" / "MRCLAM_Dataset7"
    fetched.mkdir(parents=True)
    assert default_mrclam_dir() == fetched
    lines = [line for line in _table_with(markdown_table, row).splitlines() if "MRCLAM" in line]
    assert lines == [f"| MRCLAM Dataset 7, robot 1 ({row['mrclam_note']}) | – s | – | – |"]


def _table_with(markdown_table, mrclam: dict) -> str:
    """The markdown of a tiny benchmark run with `mrclam` as its MRCLAM result."""
    from benchmarks.bench import BenchConfig, run_benchmarks

    r = run_benchmarks(
        BenchConfig(
            sizes=(2, 4),
            replay_repeats=1,
            step_repeats=1,
            literal_repeats=1,
            startup_repeats=1,
            loop_runs=1,
            loop_steps=40,
        ),
        command="test",
    )
    return markdown_table({**r, **mrclam})


def test_bench_reports_the_whole_process_startup_times_with_their_targets():
    """The "startup" section: medians of ``--help`` and ``run octagon-2laps``; no timing test."""
    from benchmarks.startup import TARGETS_S, startup_lines, startup_times

    r = startup_times(1, Path(__file__).resolve().parents[2] / "data" / "runs")
    assert set(r["startup_s"]) == {"help", "run"}
    assert all(positive(s) for s in r["startup_s"].values())
    assert r["startup_target_s"] == TARGETS_S == {"help": 0.3, "run": 0.7}
    lines = startup_lines(r)
    assert lines[1].startswith("| startup (whole process, median of 1) |")
    assert "`python -m ekfslam --help` |" in lines[3] and lines[3].endswith("| 0.3 s |")
    assert "`python -m ekfslam run octagon-2laps` |" in lines[4] and lines[4].endswith("| 0.7 s |")


@pytest.mark.parametrize(
    "make",
    [
        lambda: BenchConfig(sizes=(-5,)),
        lambda: BenchConfig(sizes=()),
        lambda: BenchConfig(replay_repeats=0),
        lambda: BenchConfig(loop_steps=1),
    ],
)
def test_a_bad_bench_config_is_our_config_error_and_still_a_value_error(make):
    with pytest.raises(ConfigError) as info:
        make()
    assert isinstance(info.value, EkfSlamError) and isinstance(info.value, ValueError)
