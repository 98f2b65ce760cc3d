"""Tests of `replay(run, keyframes=F)`: copies of the whole state at evenly spread moments."""

from __future__ import annotations

import numpy as np
import pytest

from ekfslam import replay
from ekfslam.core.association import AssociationConfig
from ekfslam.errors import ConfigError
from ekfslam.logs.edit import truncate


@pytest.fixture(scope="module")
def framed(square):
    return replay(square, keyframes=12)


def test_keyframes_change_nothing_in_the_replay(square, square_result, framed) -> None:
    assert square_result.keyframes is None  # the default keeps none
    np.testing.assert_array_equal(framed.mu, square_result.mu)
    np.testing.assert_array_equal(framed.Sigma, square_result.Sigma)
    np.testing.assert_array_equal(framed.history.pose_cov, square_result.history.pose_cov)


def test_keyframes_run_from_the_start_to_the_final_state(square, framed) -> None:
    kf = framed.keyframes
    n_det = len(square.detections.t)
    assert len(kf) == 12
    assert (kf.detections[0], kf.dim[0], kf.t[0]) == (0, 3, pytest.approx(square.controls.t[0]))
    np.testing.assert_array_equal(kf.mu[0, :3], square.meta.nominal_start)
    assert kf.detections[-1] == n_det and kf.t[-1] == pytest.approx(square.controls.t[-1])
    np.testing.assert_array_equal(kf.mu[-1], framed.mu)
    np.testing.assert_array_equal(kf.Sigma[-1], framed.Sigma)
    # evenly spread over the detections: 0, N/10, ..., N, then the end
    np.testing.assert_array_equal(kf.detections[:-1], np.round(np.linspace(0, n_det, 11)))
    assert np.all(np.diff(kf.t) >= 0) and np.all(np.diff(kf.dim) >= 0)
    assert list(kf.landmark_ids) == list(framed.landmarks)


def test_a_keyframe_is_the_state_after_its_detections(square, framed) -> None:
    kf = framed.keyframes
    f = 5
    i = int(kf.detections[f])
    cut = replay(truncate(square, float(square.detections.t[i - 1]), max_detections=i))
    d = int(kf.dim[f])
    assert len(cut.mu) == d
    np.testing.assert_allclose(kf.mu[f, :d], cut.mu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(kf.Sigma[f, :d, :d], cut.Sigma, rtol=0, atol=1e-15)
    assert np.isnan(kf.mu[f, d:]).all() and np.isnan(kf.Sigma[f, d:, :]).all()  # not seen yet


def test_keyframes_with_hidden_ids_end_at_the_final_state(square) -> None:
    result = replay(square, keyframes=6, association=AssociationConfig(method="nn"))
    kf = result.keyframes
    assert 2 <= len(kf) <= 6 and kf.detections[0] == 0
    np.testing.assert_array_equal(kf.mu[-1], result.mu)


@pytest.mark.parametrize("bad", [1, 0, -3, 2.5, True, "four", 10**20])
def test_keyframes_must_be_a_whole_number_of_at_least_two(square, bad) -> None:
    # 10**20 asked numpy for 10**20 copies of the state: "Maximum allowed size exceeded" (issue 27)
    with pytest.raises(ConfigError, match="keyframes must be a whole number from 2 to 100000"):
        replay(square, keyframes=bad)
