"""Tests of ekfslam.core.recovery: the pose covariance widened after a run of rejections."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ekfslam.analysis.evaluation import summarize
from ekfslam.core.filter.history import Outcome
from ekfslam.core.models import observation
from ekfslam.core.recovery import Recovery, RecoveryConfig
from ekfslam.errors import ConfigError
from ekfslam.logs.runlog import Controls, read_run
from ekfslam.pipeline import replay
from ekfslam.strategies import KnownIds

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


class ScriptedFilter:
    """Answers `update` with the outcomes it is given; records the predictions it is asked."""

    def __init__(self, outcomes: list[Outcome]) -> None:
        self.outcomes = list(outcomes)
        self.pose = np.array([0.0, 0.0, 0.0])
        self.predictions: list[tuple[np.ndarray, np.ndarray, float]] = []
        self.counts = "the filter's"

    def update(self, landmark_id, z, Q, t=None) -> Outcome:
        return self.outcomes.pop(0)

    def landmark(self, landmark_id):
        return np.array([2.0, 0.0]) if landmark_id % 2 else np.array([0.0, 3.0]), np.eye(2)

    def predict(self, u, R, t=None) -> None:
        self.predictions.append((np.asarray(u), np.asarray(R), t))


def _sight(recovery: Recovery, landmark_id: int, t: float, dr: float, db: float) -> Outcome:
    r, b = observation(recovery.filter.pose, recovery.filter.landmark(landmark_id)[0])
    return recovery.update(landmark_id, (r + dr, b + db), np.eye(2), t)


def test_after_the_run_of_rejections_the_pose_covariance_grows_by_their_mean_square() -> None:
    config = RecoveryConfig(after=4, landmarks=2)
    fake = ScriptedFilter([Outcome.REJECTED] * 4)
    rec = Recovery(fake, config)
    innovations = [(0.3, 0.1), (-0.1, 0.2), (0.2, -0.1), (0.4, 0.3)]
    for k, (dr, db) in enumerate(innovations):
        _sight(rec, k % 2, float(k), dr, db)
    assert len(fake.predictions) == 1
    u, R, t = fake.predictions[0]
    nu = np.array(innovations)
    expected = np.diag([np.mean(nu[:, 0] ** 2)] * 2 + [np.mean(nu[:, 1] ** 2)])
    np.testing.assert_allclose(R, expected, atol=1e-12)
    assert u.tolist() == [0.0, 0.0, 0.0] and t == 3.0
    assert rec.times == [3.0]
    assert rec.counts == "the filter's"  # everything else is the filter's


def test_an_accepted_sighting_resets_the_run_and_one_landmark_alone_never_triggers() -> None:
    outcomes = [Outcome.REJECTED] * 3 + [Outcome.ACCEPTED] + [Outcome.REJECTED] * 3
    fake = ScriptedFilter(outcomes)
    rec = Recovery(fake, RecoveryConfig(after=4, landmarks=2))
    for k in range(7):
        _sight(rec, k % 2, float(k), 0.5, 0.5)
    assert fake.predictions == []
    lone = ScriptedFilter([Outcome.REJECTED] * 10)
    rec = Recovery(lone, RecoveryConfig(after=4, landmarks=2))
    for k in range(10):  # a biased range on one landmark is not a lost pose
        _sight(rec, 1, float(k), 0.5, 0.0)
    assert lone.predictions == []


def test_a_new_landmark_neither_counts_nor_resets() -> None:
    outcomes = [Outcome.REJECTED, Outcome.INITIALISED, Outcome.REJECTED]
    fake = ScriptedFilter(outcomes)
    rec = Recovery(fake, RecoveryConfig(after=2, landmarks=2))
    for k in range(3):
        _sight(rec, k, float(k), 0.1, 0.1)
    assert len(fake.predictions) == 1


def test_bad_settings_are_refused() -> None:
    for bad in ({"after": 0}, {"landmarks": 0}, {"after": 2, "landmarks": 3}, {"after": True}):
        with pytest.raises(ConfigError):
            RecoveryConfig(**bad)


def test_a_replay_that_never_rejects_is_the_same_with_recovery_bit_for_bit() -> None:
    run = read_run(RUNS / "square-2laps")
    plain, watched = replay(run), replay(run, association=KnownIds(RecoveryConfig()))
    np.testing.assert_array_equal(plain.mu, watched.mu)
    np.testing.assert_array_equal(plain.Sigma, watched.Sigma)
    assert watched.diagnosis.recoveries == ()


def test_a_robot_whose_odometry_dropped_out_relocalises_and_the_diagnosis_says_when() -> None:
    """The octagon with its wheels logged as still for 2 s while the robot drove on: the pose
    ends 0.2 m behind, every later sighting fails the gate, and the map bends (0.20 m). With
    recovery the pose covariance is widened once, at the 20th rejection, and the map is the
    clean run's (0.006 m)."""
    run = read_run(RUNS / "octagon-2laps")
    c = run.controls
    still = np.where(((c.t >= 35.0) & (c.t < 37.0))[:, None], 0.0, c.values)
    dropped = dataclasses.replace(run, controls=Controls(t=c.t, kind=c.kind, values=still))
    lost = replay(dropped)
    found = replay(dropped, association=KnownIds(RecoveryConfig()))
    assert lost.diagnosis.verdict == "lost" and lost.diagnosis.recoveries == ()
    assert lost.diagnosis.lost_after == pytest.approx(36.0, abs=1.0)
    assert found.diagnosis.verdict == "ok"
    assert found.diagnosis.recoveries == pytest.approx((38.0,), abs=0.5)
    assert found.counts.predictions == lost.counts.predictions + 1
    assert summarize(dropped, lost).alignment.mean_error > 0.15
    assert summarize(dropped, found).alignment.mean_error < 0.01
    assert "recovered 1 time(s)" in found.diagnosis.line()


def test_recovery_is_a_recovery_config() -> None:
    with pytest.raises(ConfigError, match="KnownIds: recovery must be"):
        KnownIds(recovery={"after": 20})
