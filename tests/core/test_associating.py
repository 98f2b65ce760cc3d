"""The associating correction: tentative landmarks, spurious sightings, ambiguous ones."""

from __future__ import annotations

import numpy as np
import pytest

from ekfslam.core.association import (
    UNPAIRED,
    AssociationConfig,
    individual_nis,
    jcbb,
    nearest_neighbour,
)
from ekfslam.core.filter.associating import AMBIGUOUS, AssociatingFilter
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter.mht import HypothesisBank
from ekfslam.core.models import observation, observation_noise

Q = observation_noise(0.01, 0.01)
LANDMARKS = np.array([[2.0, 0.0], [0.0, 2.0]])
POSE = np.zeros(3)  # the robot stands still, its pose known: only the decisions matter


def sightings(*points):
    return np.array([observation(POSE, p) for p in points])


def make(method: str = "jcbb") -> AssociatingFilter:
    return AssociatingFilter(EKFSLAM(POSE), AssociationConfig(method=method, tentative_life=5.0))


def test_a_landmark_becomes_permanent_when_seen_again_and_is_then_associated():
    f = make()
    assert f.observe(sightings(*LANDMARKS), Q, 0.0) == [UNPAIRED, UNPAIRED]  # tentative
    assert f.observe(sightings(*LANDMARKS), Q, 1.0) == [0, 1]  # confirmed: new landmarks
    assert f.observe(sightings(LANDMARKS[1], LANDMARKS[0]), Q, 2.0) == [1, 0]
    log = f.finish()
    assert (log.counts.tentative, log.counts.confirmed, log.counts.associated) == (2, 2, 2)
    assert f.ekf.n_landmarks == 2


def test_a_spurious_sighting_does_not_become_a_landmark():
    f = make("nn")
    for t in range(3):
        f.observe(sightings(*LANDMARKS), Q, float(t))
    f.observe(sightings(*LANDMARKS, [-1.5, -1.0]), Q, 3.0)  # one sighting of nothing
    for t in range(4, 12):
        f.observe(sightings(*LANDMARKS), Q, float(t))
    log = f.finish()
    assert f.ekf.n_landmarks == 2
    assert log.counts.tentative_discarded == 1  # expired after tentative_life
    assert log.decision[8] == "tentative"


def test_a_landmark_never_seen_again_is_discarded_at_the_end():
    f = make()
    f.observe(sightings(LANDMARKS[0]), Q, 0.0)
    f.observe(sightings(LANDMARKS[0]), Q, 1.0)
    f.observe(sightings(LANDMARKS[0], LANDMARKS[1]), Q, 2.0)  # the second, once only
    log = f.finish()
    assert f.ekf.n_landmarks == 1
    assert log.counts.tentative_discarded == 1


def test_a_sighting_between_the_gate_and_the_new_landmark_threshold_is_dropped():
    f = make()
    f.observe(sightings(LANDMARKS[0]), Q, 0.0)
    f.observe(sightings(LANDMARKS[0]), Q, 1.0)
    _, S = f.ekf.landmark(0)
    # a range off by ~4 σ of the innovation: NIS about 16, between 9.21 and 23.0
    sigma = np.sqrt(S[0, 0] + Q[0, 0])
    z = observation(POSE, LANDMARKS[0]) + np.array([4.0 * sigma, 0.0])
    mean_before = f.ekf.mu.copy()
    assert f.observe(z[None, :], Q, 2.0) == [UNPAIRED]
    log = f.finish()
    assert log.decision[-1] == AMBIGUOUS and log.counts.ambiguous == 1
    np.testing.assert_array_equal(f.ekf.mu, mean_before)  # dropped: the state is untouched


def correlated(linearization, seed, count, motion, method):
    """A correlated map (pose uncertain, `count` landmarks seen from two poses), its
    associating filter, and the landmarks' true places."""
    rng = np.random.default_rng(seed)
    ekf = EKFSLAM(
        np.zeros(3), np.diag([0.04, 0.04, 0.01]), FilterConfig(linearization=linearization)
    )
    marks = rng.uniform(-4.0, 4.0, size=(count, 2))
    for j, p in enumerate(marks):
        ekf.update(j, observation(np.zeros(3), p), Q)
    ekf.predict(*motion)
    return AssociatingFilter(ekf, AssociationConfig(method=method)), marks, rng


@pytest.mark.parametrize("linearization", ["standard", "invariant"])
def test_the_compiled_nearest_neighbour_decides_as_the_numpy_reference(linearization):
    # a correlated map (pose uncertain, landmarks seen from two poses) and sightings near,
    # between and far from its landmarks: nearest.nearest agrees with individual_nis then
    # nearest_neighbour on every pairing, and on the smallest NIS to rounding. The invariant
    # filter's kernel reads its ξ covariance, the numpy one the Cartesian Σ: the same S.
    motion = ([0.3, 0.1, 0.2], np.diag([0.01, 0.01, 0.004]))
    f, marks, rng = correlated(linearization, 3, 12, motion, "nn")
    pose = f.ekf.pose
    points = np.vstack([marks + rng.normal(0, 0.05, marks.shape), rng.uniform(-5, 5, (8, 2))])
    zs = np.array([observation(pose, p) for p in points])
    nu, P = f.predicted(zs)
    nis = individual_nis(nu, P, np.broadcast_to(Q, (len(zs), 2, 2)))
    pairing, smallest = f._nearest(zs, Q)
    assert pairing == nearest_neighbour(nis, f.config.gate).tolist()
    assert sum(p != UNPAIRED for p in pairing) >= 12
    np.testing.assert_allclose(smallest, nis.min(axis=1), rtol=1e-9)


def test_a_drifted_robot_does_not_confirm_a_tentative_with_its_neighbours_sighting():
    # the pose is very uncertain (a robot deep into a loop) but did not move between the two
    # sightings: their shared pose error cancels, so a sighting 0.3 m away starts its own
    # tentative, and a sighting of the same place confirms
    ekf = EKFSLAM(POSE, np.diag([0.25, 0.25, 0.04]))
    f = AssociatingFilter(ekf, AssociationConfig(method="nn", tentative_life=5.0))
    here, beside = np.array([3.0, 0.0]), np.array([3.0, 0.3])
    assert f.observe(sightings(here), Q, 0.0) == [UNPAIRED]
    assert f.observe(sightings(beside), Q, 1.0) == [UNPAIRED]  # a second tentative
    assert f.observe(sightings(here), Q, 2.0) == [0]  # confirms the first
    assert f.finish().counts.tentative == 2 and f.ekf.n_landmarks == 1


def test_the_second_tag_of_a_close_pair_seen_with_the_first_becomes_a_landmark():
    """B lies inside A's gate; A is mapped and seen with B. JCBB pairs A's sighting with A, and
    one landmark gives one sighting per time, so B's is of no mapped landmark: it starts a
    tentative and is confirmed, rather than being ambiguous against A for ever."""
    a, b = LANDMARKS[0], LANDMARKS[0] + [0.0, 0.05]
    f = make("jcbb")
    f.observe(sightings(a), Q, 0.0)
    f.observe(sightings(a), Q, 1.0)  # A is mapped
    nu, P = f.predicted(sightings(b))
    assert individual_nis(nu, P, Q[None])[0, 0] < 9.21  # B alone would be taken for A
    for t in (2.0, 3.0, 4.0):
        f.observe(sightings(a, b), Q, t)
    log = f.finish()
    assert f.ekf.n_landmarks == 2
    assert log.counts.ambiguous == 0
    assert log.decision[-2:] == ("associated", "associated")
    assert np.allclose(f.ekf.landmark(1)[0], b, atol=0.01)


def test_a_sighting_taken_while_turning_is_uncertain_in_bearing_by_the_time_sigma():
    """A bearing 0.06 rad off (6 sigma) is no sighting of the landmark for a robot standing
    still, and is one when the robot turns at 0.5 rad/s and its time stamp may be 0.2 s off."""
    z = observation(POSE, LANDMARKS[0]) + np.array([0.0, 0.06])
    for omega, expected in ((0.0, UNPAIRED), (0.5, 0)):
        ekf = EKFSLAM(POSE)
        f = AssociatingFilter(ekf, AssociationConfig(method="jcbb", time_sigma=0.2))
        f.observe(sightings(LANDMARKS[0]), Q, 0.0)
        f.observe(sightings(LANDMARKS[0]), Q, 1.0)
        assert f.observe(z[None], Q, 2.0, omega) == [expected]


def test_decide_says_what_observe_would_pair_and_changes_nothing():
    for method in ("nn", "jcbb"):
        f = make(method)
        f.observe(sightings(*LANDMARKS), Q, 0.0)
        f.observe(sightings(*LANDMARKS), Q, 1.0)
        mu, Sigma = f.ekf.mu.copy(), f.ekf.Sigma.copy()
        assert f.decide(sightings(LANDMARKS[1], LANDMARKS[0]), Q) == [1, 0]
        np.testing.assert_array_equal(f.ekf.mu, mu)
        np.testing.assert_array_equal(f.ekf.Sigma, Sigma)
        assert len(f.finish().estimated) == 4  # the decision was not logged


@pytest.mark.parametrize("linearization", ["standard", "invariant"])
def test_the_compiled_jcbb_decides_as_the_numpy_reference(linearization):
    # as above for JCBB: the compiled H Σ Hᵀ and search against `predicted` (Cartesian Σ) and
    # the numpy `jcbb`. Before, the kernel read the invariant filter's ξ covariance with the
    # standard H (heading column -1): the wrong S, other pairings.
    motion = ([0.3, 0.1, 0.4], np.diag([0.01, 0.01, 0.02]))
    f, marks, rng = correlated(linearization, 5, 10, motion, "jcbb")
    pose = f.ekf.pose
    points = np.vstack([marks[:6] + rng.normal(0, 0.05, (6, 2)), rng.uniform(-5, 5, (2, 2))])
    zs = np.array([observation(pose, p) for p in points])
    nu, P = f.predicted(zs)
    Qs = np.broadcast_to(Q, (len(zs), 2, 2))
    want = jcbb(nu, P, Qs, f.config.gate, f.config.joint_probability, f.config.node_budget)
    got, _ = f._jcbb(zs, Q)
    assert got.pairing.tolist() == want.pairing.tolist()
    assert sum(p != UNPAIRED for p in got.pairing) >= 5
    np.testing.assert_allclose(got.joint_nis, want.joint_nis, rtol=1e-9)


@pytest.mark.parametrize(
    ("rule", "k", "expected"),
    [
        ("threshold", 4.0, AMBIGUOUS),
        ("density", 4.0, "tentative"),
        ("density", 3.4, AMBIGUOUS),
    ],
)
def test_a_sighting_no_landmark_explains_better_than_a_new_one_starts_a_landmark(rule, k, expected):
    """A range-noisy camera (0.5 m, 0.03 rad, as MRCLAM's) and a landmark A mapped from one
    sighting (the second confirms it): S = diag(0.5 m², 0.0018 rad²), log det 2πS = -3.34. A
    sighting k σ off in bearing (NIS k², outside the 9.21 gate): by the threshold rule ambiguous
    below NIS 23.0; by the likelihood ratio with the density e^-5 new once -½(NIS - 3.34) < -5,
    at NIS > 13.3, so the close neighbour of a mapped tag (NIS 16) is founded, one at NIS 11.6
    still dropped."""
    Qn = observation_noise(0.5, 0.03)
    a = np.array([3.0, 0.0])
    f = AssociatingFilter(EKFSLAM(POSE), AssociationConfig(method="jcbb", new_rule=rule))
    f.observe(sightings(a), Qn, 0.0)
    f.observe(sightings(a), Qn, 1.0)  # A is mapped
    S_z = f.predicted(sightings(a))[1] + Qn
    np.testing.assert_allclose(np.diag(S_z), [0.5, 0.0018], rtol=1e-6)
    assert np.log(np.linalg.det(2 * np.pi * S_z)) == pytest.approx(-3.34, abs=0.005)
    z = observation(POSE, a) + np.array([0.0, k * np.sqrt(S_z[1, 1])])
    nu, P = f.predicted(z[None])
    assert individual_nis(nu, P, Qn[None])[0, 0] == pytest.approx(k * k, rel=1e-6)
    assert f.observe(z[None], Qn, 2.0) == [UNPAIRED]
    assert f.finish().decision[-1] == expected


@pytest.mark.parametrize("method", ["nn", "jcbb", "mht"])
@pytest.mark.parametrize(
    ("zs", "Q", "t", "named"),
    [
        ([[1.0, np.nan]], np.eye(2) * 1e-3, 1.0, "zs"),
        ([[1.0, 0.2, 0.1]], np.eye(2) * 1e-3, 1.0, "zs"),
        ([[1.0, 0.2]], -np.eye(2), 1.0, "Q"),
        ([[1.0, 0.2]], np.zeros((2, 2)), 1.0, "Q"),
        ([[1.0, 0.2]], np.eye(2) * 1e-3, np.inf, "t"),
    ],
)
def test_observe_refuses_bad_sightings_by_name_before_the_filter_is_touched(
    method, zs, Q, t, named
):
    # observe checks the sightings of one time once, then feeds the filter unchecked: what the
    # filter's own checks caught (EKFSLAM.update) must still be caught, by the observe's name
    config = AssociationConfig(method="jcbb" if method == "mht" else method)
    ekf = EKFSLAM([0.0, 0.0, 0.0])
    target = HypothesisBank(ekf, config) if method == "mht" else AssociatingFilter(ekf, config)
    before = ekf.mu.copy(), ekf.counts
    with pytest.raises(ValueError, match=rf"\.observe: {named}\b"):
        target.observe(zs, Q, t)
    assert np.array_equal(ekf.mu, before[0]) and ekf.counts == before[1]
