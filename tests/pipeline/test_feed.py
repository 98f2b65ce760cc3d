"""`feed` hands the filter the run's arrays unchecked, in one call (`EKFSLAM.feed`: the run was
checked once, when read or handed to `replay`); what the filter computes is what its steps give,
one call each with every argument checked."""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np
import pytest
from stepwise import one_by_one

from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.logs.runlog import read_run
from ekfslam.pipeline import replay

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


@pytest.mark.parametrize("name", ["octagon-2laps", "square-2laps-realistic"])
def test_the_replays_unchecked_feed_gives_the_checked_steps_result_bit_for_bit(name, monkeypatch):
    run = read_run(RUNS / name)
    fast = replay(run)  # `EKFSLAM.feed`: the run in one call
    calls = {"update": 0, "predict_many": 0}
    for method in calls:
        original = getattr(EKFSLAM, method)

        def counted(self, *args, _original=original, _method=method, **kwargs):
            assert kwargs["validate"] is True
            calls[_method] += 1
            return _original(self, *args, **kwargs)

        monkeypatch.setattr(EKFSLAM, method, counted)
    monkeypatch.setattr(EKFSLAM, "feed", functools.partialmethod(one_by_one, validate=True))
    slow = replay(run)
    assert calls["update"] == len(run.detections.t) and calls["predict_many"] > 0
    np.testing.assert_array_equal(slow.mu, fast.mu)
    np.testing.assert_array_equal(slow.Sigma, fast.Sigma)
    for field in dataclasses.fields(fast.history):
        a, b = getattr(fast.history, field.name), getattr(slow.history, field.name)
        np.testing.assert_array_equal(a, b)
    assert slow.counts == fast.counts
