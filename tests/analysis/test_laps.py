"""Tests of ekfslam.analysis.laps: per-lap numbers, revisits, the size sweep."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ekfslam import EKFSLAM
from ekfslam.analysis.alignment import align
from ekfslam.analysis.frames_of_reference import tags_in_filter_frame
from ekfslam.analysis.laps import lap_statistics, lap_times, revisits, size_sweep
from ekfslam.errors import EkfSlamError
from ekfslam.pipeline import replay_until


def test_lap_times_are_every_fourth_waypoint_of_the_square(square) -> None:
    times = square.meta.simulation["waypoint_times"]
    np.testing.assert_array_equal(lap_times(square), [times[4], times[8]])
    with pytest.raises(EkfSlamError, match="not a simulated run"):
        lap_times(replace(square, meta=replace(square.meta, simulation=None)))


def test_lap_statistics_of_the_square_run(square) -> None:
    laps = lap_statistics(square)
    assert [s.lap for s in laps] == [1, 2]
    assert laps[0].t_start == 0.0 and laps[1].t_start == laps[0].t_end
    assert all(s.landmarks == 8 for s in laps)
    assert laps[1].map_sd < laps[0].map_sd  # the seed's "driving multiple times"
    for s in laps:
        assert 0 < s.map_error < 0.05 and 0 < s.position_rmse < 0.05
        assert s.map_error <= s.map_error_unaligned  # the fit can only lower the mean distance


def test_revisits_find_sightings_after_a_gap() -> None:
    ekf = EKFSLAM([0.0, 0.0, 0.0])
    Q = np.diag([0.01, 0.01])
    for t, i in ((0.0, 1), (1.0, 2), (5.0, 1), (20.0, 1), (30.0, 2), (31.0, 2)):
        ekf.update(i, [1.0, 0.5 * i], Q, t=t)
    times, ids = revisits(ekf.history(), gap=10.0)
    np.testing.assert_array_equal(times, [20.0, 30.0])
    np.testing.assert_array_equal(ids, [1, 2])


def test_size_sweep_gives_one_scored_point_per_run() -> None:
    points = size_sweep(("octagon",), (0.7,), seeds=(3,), laps=1)
    assert len(points) == 1
    p = points[0]
    assert (p.trajectory, p.size, p.seed, p.landmarks) == ("octagon", 0.7, 3, 8)
    assert 0 < p.map_error < 0.05 and 0 < p.position_rmse < 0.05


def test_lap_statistics_from_one_replay_equal_a_replay_per_lap(square) -> None:
    """The map at each lap's end is exactly what replaying the run up to that time gives."""
    tags = tags_in_filter_frame(square)
    for stats, t1 in zip(lap_statistics(square), lap_times(square), strict=True):
        at_end = replay_until(square, float(t1))
        lm = at_end.landmarks
        assert stats.landmarks == len(lm)
        assert stats.map_error == align(lm, square.meta.tag_map).mean_error
        assert stats.map_error_unaligned == float(
            np.mean([np.hypot(*(lm[i] - tags[i])) for i in lm])
        )
        spread = [math.sqrt(np.trace(c)) for c in at_end.landmark_covariances.values()]
        assert stats.map_sd == float(np.mean(spread))
