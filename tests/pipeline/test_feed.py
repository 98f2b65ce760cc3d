"""`_feed` hands the filter the run's arrays unchecked (``validate=False``: the run was checked
once, when read or handed to `replay`); what the filter computes is what a checked feed gives."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.logs.runlog import read_run
from ekfslam.pipeline import replay

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


@pytest.mark.parametrize("name", ["octagon-2laps", "square-2laps-realistic"])
def test_an_unchecked_feed_gives_the_checked_feeds_result_bit_for_bit(name, monkeypatch):
    run = read_run(RUNS / name)
    fast = replay(run)
    calls = {"update": 0, "predict_many": 0}
    for method in calls:
        original = getattr(EKFSLAM, method)

        def checked(self, *args, _original=original, _method=method, **kwargs):
            assert kwargs.pop("validate", True) is False  # the feed asked for no checks
            calls[_method] += 1
            return _original(self, *args, validate=True, **kwargs)

        monkeypatch.setattr(EKFSLAM, method, checked)
    slow = replay(run)
    assert calls["update"] == len(run.detections.t) and calls["predict_many"] > 0
    np.testing.assert_array_equal(slow.mu, fast.mu)
    np.testing.assert_array_equal(slow.Sigma, fast.Sigma)
