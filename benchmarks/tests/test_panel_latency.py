"""``python -m benchmarks tune --bench``: the panel's move timed in process, its pieces in order
(no timing assertions: the machine is shared)."""

from __future__ import annotations

import pytest

from benchmarks.panel import benchmark
from ekfslam.logs.runlog import read_run
from ekfslam.ui.tuning import RUNS_DIR


@pytest.fixture(scope="module")
def runs():
    square = read_run(RUNS_DIR / "square-2laps")
    return {"square": lambda: square}


def test_the_in_process_benchmark_times_the_blitted_move(runs):
    report = benchmark({"square": runs["square"]}, repeats=2)["square"]
    assert 0 < report["replay_ms"] < report["blit_ms"]
    assert 0 < report["frame_ms"] < report["blit_ms"]
    assert 10 < report["frame_kib"] < 500  # a diff frame: the changed pixels of 900 x 600


def test_the_benchmark_reports_each_piece_of_a_move_below_the_whole(runs):
    report = benchmark(runs, repeats=1)["square"]
    assert report["samples"] == 1
    assert 0 < report["replay_ms"] < report["update_ms"] < report["median_ms"]
    assert 0 < report["draw_ms"] < report["median_ms"]
