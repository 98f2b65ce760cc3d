"""The classroom benchmark's bookkeeping (the benchmark itself is ``tune --classroom N``)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from benchmarks.classroom import children, rss_mb, session_row, sessions_holding_target


def test_a_row_holds_the_target_only_when_median_and_p90_both_do():
    row = session_row(3, [10, 20, 30, 40, 50, 45, 35, 25, 15, 100], [250.0, 260.0], 90.0)
    assert row["median_ms"] == pytest.approx(32.5)
    assert row["p90_ms"] == pytest.approx(55.0)
    assert row["holds_target"] and row["moves"] == 10 and row["kernel_rss_mb"] == [250.0, 260.0]
    assert not session_row(1, [49] * 8 + [200, 200], [], 0.0)["holds_target"]
    assert not session_row(1, [60] * 5, [], 0.0)["holds_target"]  # both over


def test_the_count_held_is_the_last_before_the_first_miss():
    rows = [session_row(n, [ms] * 4, [], 0.0) for n, ms in ((1, 30), (2, 45), (3, 70), (4, 40))]
    assert sessions_holding_target(rows) == 2  # 4 held by luck after 3 missed: not counted
    assert sessions_holding_target(rows[2:]) == 0
    assert sessions_holding_target([]) == 0


def test_memory_and_children_come_from_proc():
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        assert child.pid in children(os.getpid())
        assert 1.0 < rss_mb(child.pid) < 1000.0  # a bare interpreter: a few MiB
    finally:
        child.kill()
        child.wait()
    assert rss_mb(child.pid) == 0.0 and child.pid not in children(os.getpid())
