"""The studies give the same numbers in this process and on two local processes; a Dask
scheduler that cannot be reached is one line."""

from __future__ import annotations

from studies_cli import studies_main

from ekfslam.analysis import parallel
from studies import robustness


def test_outlier_study_is_the_same_on_one_and_two_processes():
    one = robustness.outlier_study("octagon", 2, 0.1, first_seed=3, jobs=1)
    two = robustness.outlier_study("octagon", 2, 0.1, first_seed=3, jobs=2)
    labels = [c.label for c in two.cases]
    assert labels == [k for k in ("clean", "wrong_id", "range", "mixed") for _ in range(2)]
    assert [c.gate is None for c in two.cases] == [False, True] * 4
    assert two.cases == one.cases
    assert two.case("clean").ratio == 1.0
    assert two.case("wrong_id").injected > 0


def test_an_unreachable_scheduler_is_one_line_exit_2(monkeypatch, capsys):
    monkeypatch.setattr(parallel, "DASK_TIMEOUT", 0.5)
    code = studies_main(["consistency", "nees", "--runs", "2", "--dask", "tcp://127.0.0.1:1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "--dask tcp://127.0.0.1:1" in err[0], err
