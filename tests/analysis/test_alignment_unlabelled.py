"""Matching an estimated map to the true one by position, with no ids (eq. 17 without a mapping)."""

from __future__ import annotations

import numpy as np
import pytest

from ekfslam.analysis.alignment import align
from ekfslam.analysis.alignment_unlabelled import match_by_position
from ekfslam.errors import AlignmentError
from ekfslam.geometry import transform_points

# MRCLAM Dataset 7's kind of map: close pairs 0.2 m apart
TRUTH = {
    6: (0.59, -4.28),
    7: (0.68, -4.45),
    9: (2.81, -4.41),
    11: (3.05, -2.54),
    12: (2.86, -2.39),
    14: (1.69, 2.66),
    16: (3.14, 4.00),
    19: (1.41, 4.53),
}


def estimated_map(seed: int = 1):
    """The truth seen from a drifted start (0.5 m, 0.3 rad), 2 cm noise, renamed in a shuffled
    order; plus a landmark of nothing 1.5 m from every true one and a duplicate of 14."""
    rng = np.random.default_rng(seed)
    ids = list(TRUTH)
    order = rng.permutation(len(ids))
    Y = np.array([TRUTH[ids[j]] for j in order])
    inverse = np.array([-0.5, 0.2, -0.3])  # world -> the filter's frame
    X = transform_points(inverse, Y) + rng.normal(0, 0.02, Y.shape)
    est = {e: X[e] for e in range(len(ids))}
    expected = {e: ids[j] for e, j in enumerate(order)}
    est[8] = transform_points(inverse, np.array([[-1.0, 0.0]]))[0]  # nothing there
    dup = next(e for e, t in expected.items() if t == 14)
    est[9] = est[dup] + np.array([0.35, 0.0])  # a second, worse copy of 14
    return est, expected, dup


def test_the_ids_are_recovered_and_the_spurious_landmarks_left_unmatched():
    est, expected, _ = estimated_map()
    found = match_by_position(est, TRUTH)
    assert found.mapping == expected
    assert found.unmatched == [8, 9]
    Y = np.array(list(TRUTH.values()))
    gaps = np.hypot(*(Y[:, None] - Y[None]).transpose(2, 0, 1)) + np.diag([np.inf] * len(Y))
    assert found.cutoff == pytest.approx(0.5 * np.median(gaps.min(axis=1)))  # 0.51 m here
    # eq. (17) over the matches: the drift undone, the noise left
    a = align({found.mapping[e]: est[e] for e in found.mapping}, TRUTH)
    assert a.mean_error < 0.04
    assert a.theta0 == pytest.approx(0.3, abs=0.02)


def test_matching_needs_two_landmarks_of_each():
    with pytest.raises(AlignmentError, match="at least 2 estimated"):
        match_by_position({0: (0.0, 0.0)}, TRUTH)


def test_a_symmetric_map_is_matched_with_the_least_turn():
    """Four tags on a square fit as well turned by a quarter: the start error is the small one."""
    truth = {10: (1.0, 1.0), 11: (-1.0, 1.0), 12: (-1.0, -1.0), 13: (1.0, -1.0)}
    Y = np.array(list(truth.values()))
    X = transform_points(np.array([0.05, -0.03, 0.1]), Y)  # estimated: ids 0..3 in that order
    found = match_by_position(dict(enumerate(X)), truth)
    assert found.mapping == {0: 10, 1: 11, 2: 12, 3: 13}
    assert found.transform[2] == pytest.approx(-0.1)


def test_ids_given_as_strings_match_as_the_same_ints():
    """Keys read back from JSON are strings: "10" sorts before "9" as text, and the positions
    were once taken in that order while the ids were sorted as numbers, so each id got another
    landmark's position."""
    est, expected, _ = estimated_map()
    as_text = match_by_position({str(e): p for e, p in est.items()}, TRUTH)
    truth_text = match_by_position(est, {str(t): p for t, p in TRUTH.items()})
    assert as_text.mapping == expected
    assert truth_text.mapping == expected
