"""Tests of ekfslam.pipeline's partial replays: the state at a time, before a detection."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ekfslam import NoiseConfig, read_run, replay
from ekfslam.analysis.laps import lap_times
from ekfslam.core.steps import update_steps
from ekfslam.errors import EkfSlamError
from ekfslam.logs.edit import truncate
from ekfslam.pipeline import landmark_slots, prior_before, replay_until, replay_until_each

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


def test_replay_until_a_detection_time_is_the_full_replay_at_that_moment(
    square, square_result
) -> None:
    h = square_result.history
    t_cut = float(square.detections.t[300])
    part = replay_until(square, t_cut)
    last = np.flatnonzero(h.t <= t_cut)[-1]  # the full replay's last event at or before the cut
    np.testing.assert_array_equal(part.mu[:3], h.pose[last])
    np.testing.assert_array_equal(part.Sigma[:3, :3], h.pose_cov[last])
    assert part.history.t[-1] == t_cut


def test_replay_until_the_end_is_the_full_replay(square, square_result) -> None:
    whole = replay_until(square, float(square.controls.t[-1]))
    np.testing.assert_allclose(whole.mu, square_result.mu, atol=1e-12)
    np.testing.assert_allclose(whole.Sigma, square_result.Sigma, atol=1e-12)


def test_landmark_slots_follow_the_order_of_first_sightings(square, square_result) -> None:
    ids = square.detections.tag_id
    _, first = np.unique(ids, return_index=True)
    expected = [int(ids[i]) for i in sorted(first)]
    assert landmark_slots(square_result) == expected


def test_landmark_slots_detect_a_result_whose_order_is_not_the_state_order(square_result) -> None:
    shuffled = dict(reversed(list(square_result.landmarks.items())))
    with pytest.raises(EkfSlamError, match="not in slot"):
        landmark_slots(replace(square_result, landmarks=shuffled))


def test_prior_before_and_update_steps_reproduce_the_replay(square) -> None:
    k = 309  # tag 1 seen again at 28.2 s
    prior = prior_before(square, k)
    slots = landmark_slots(prior)
    z = [square.detections.range[k], square.detections.bearing[k]]
    steps = update_steps(
        prior.mu, prior.Sigma, slots.index(int(square.detections.tag_id[k])), z, NoiseConfig().Q
    )
    after = replay(truncate(square, float(square.detections.t[k]), max_detections=k + 1))
    np.testing.assert_allclose(steps.mu_post, after.mu, atol=1e-12)
    np.testing.assert_allclose(steps.Sigma_joseph, after.Sigma, atol=1e-12)
    # the prior is predicted to the sighting's time but has not used it
    assert prior.history.t[-1] == square.detections.t[k]
    assert prior.counts.accepted + prior.counts.initialised == k


@pytest.mark.parametrize("name", ["square-2laps", "octagon-2laps"])
def test_replay_until_each_is_replay_until_at_each_time_from_one_pass(name) -> None:
    run = read_run(RUNS / name)
    # lap ends (between detections), a detection time, before any detection, and the end
    times = [
        *lap_times(run).tolist(),
        float(run.detections.t[300]),
        0.05,
        float(run.controls.t[-1]),
    ]
    full, each = replay_until_each(run, times)
    whole = replay(run)
    for a, b in (
        (full.mu, whole.mu),
        (full.Sigma, whole.Sigma),
        (full.history.pose, whole.history.pose),
    ):
        np.testing.assert_array_equal(a, b)  # the full replay's pieces are not split
    for t, state in zip(times, each, strict=True):
        alone = replay_until(run, t)
        np.testing.assert_array_equal(state.mu, alone.mu)
        np.testing.assert_array_equal(state.Sigma, alone.Sigma)
        np.testing.assert_array_equal(state.history.pose_cov, alone.history.pose_cov)
        assert state.counts == alone.counts
        assert list(state.landmarks) == list(alone.landmarks)
