"""Tests of ekfslam.logs.edit: a run without its detections, a run cut at a time."""

from __future__ import annotations

import numpy as np
import pytest

from ekfslam import NoiseConfig, replay
from ekfslam.logs.edit import truncate, without_detections


def test_dead_reckoning_heading_variance_is_the_noise_density_times_the_duration(square) -> None:
    noise = NoiseConfig()
    dead = replay(without_detections(square), noise)
    assert dead.counts.accepted == dead.counts.initialised == 0
    assert len(dead.landmarks) == 0
    duration = square.controls.t[-1] - square.controls.t[0]
    # R = V M dt Vᵀ with V's θ row (0, 0, 1): the heading variance is σθ² times the time driven
    assert dead.history.pose_cov[-1, 2, 2] == pytest.approx(noise.sigma_theta**2 * duration)


def test_truncate_keeps_what_happened_up_to_the_cut_and_holds_the_last_control(square) -> None:
    cut = truncate(square, 10.02)
    assert cut.controls.t[-1] == 10.02
    assert cut.controls.t[-2] == pytest.approx(10.0)
    np.testing.assert_array_equal(cut.controls.values[-1], cut.controls.values[-2])
    assert cut.detections.t.max() <= 10.02
    assert len(cut.detections.t) == np.count_nonzero(square.detections.t <= 10.02)
    assert cut.groundtruth.t.max() <= 10.02
    assert len(truncate(square, 10.02, max_detections=5).detections.t) == 5
    with pytest.raises(ValueError, match="before the first control"):
        truncate(square, -1.0)
