"""Tests of ekfslam.analysis.frames_of_reference: the truth in the frame the filter works in."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ekfslam import SimulationConfig, replay, simulate
from ekfslam.analysis.frames_of_reference import (
    filter_frame_transform,
    position_errors,
    tags_in_filter_frame,
    truth_in_filter_frame,
)
from ekfslam.errors import EkfSlamError
from ekfslam.logs.edit import without_detections


def test_noise_free_dead_reckoning_matches_the_truth_in_the_filter_frame() -> None:
    config = SimulationConfig(
        laps=1,
        seed=5,
        wheel_noise_sigma=0.0,
        wheel_noise_fraction=0.0,
        start_error=(0.05, -0.03, 0.1),
    )
    run = simulate(config)
    T = filter_frame_transform(run)
    framed = truth_in_filter_frame(run)
    np.testing.assert_allclose(framed.pose[0], run.meta.nominal_start, atol=1e-12)
    _, err = position_errors(run, replay(without_detections(run)).history)
    # the filter integrates eq. (6) in Euler steps, the simulator exact arcs: sub-millimetre apart
    assert err.max() < 1e-3
    # in the world frame the same path is off by about the 5.8 cm placement error
    world_err = np.hypot(*(run.groundtruth.pose[0, :2] - run.meta.nominal_start[:2]))
    assert world_err == pytest.approx(math.hypot(0.05, 0.03))
    tags = tags_in_filter_frame(run)
    a, b = run.meta.tag_map[0], run.meta.tag_map[5]
    assert np.hypot(*(tags[0] - tags[5])) == pytest.approx(np.hypot(*(a - b)))
    assert T[2] == pytest.approx(-0.1)


def test_the_filter_frame_needs_ground_truth(square) -> None:
    with pytest.raises(EkfSlamError, match="no ground truth"):
        filter_frame_transform(replace(square, groundtruth=None))
