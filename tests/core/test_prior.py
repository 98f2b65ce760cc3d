"""A map known before the run starts (`ekfslam.core.filter.prior`)."""

from __future__ import annotations

import numpy as np
import pytest

from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter.history import Outcome
from ekfslam.core.filter.prior import PriorMap, pass_record, prior_map, start_with

Q = np.diag([0.01, 0.001])


def mapped_filter() -> EKFSLAM:
    ekf = EKFSLAM((0.0, 0.0, 0.0), config=None)
    ekf.update(7, (2.0, 0.3), Q, 0.0)
    ekf.update(9, (3.0, -0.5), Q, 0.0)
    ekf.predict((0.5, 0.0, 0.1), np.diag([1e-3, 1e-3, 1e-4]), 1.0)
    ekf.update(7, (1.6, 0.2), Q, 1.0)
    return ekf


def test_the_prior_is_the_map_block_and_starts_a_fresh_filter_with_it():
    ekf = mapped_filter()
    prior = prior_map(ekf)
    np.testing.assert_array_equal(prior.means.ravel(), ekf.mu[3:])
    np.testing.assert_allclose(prior.covariance, ekf.Sigma[3:, 3:], rtol=0, atol=1e-15)
    assert prior.sightings == (2, 1)
    fresh = start_with(EKFSLAM((0.0, 0.0, 0.0), np.eye(3) * 1e-4), prior)
    assert fresh.landmark_ids == [0, 1]  # estimated ids, in slot order
    np.testing.assert_array_equal(fresh.mu[3:], ekf.mu[3:])
    np.testing.assert_allclose(fresh.Sigma[3:, 3:], prior.covariance, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(fresh.Sigma[:3, 3:], 0.0)  # no correlation with the start
    np.testing.assert_array_equal(fresh.Sigma[:3, :3], np.eye(3) * 1e-4)


def test_a_prior_goes_only_into_a_filter_that_has_taken_no_step():
    with pytest.raises(ValueError, match="has taken no step"):
        start_with(mapped_filter(), prior_map(mapped_filter()))


def test_a_prior_map_of_the_wrong_shape_is_refused():
    with pytest.raises(ValueError, match=r"means \(n, 2\) and covariance \(2n, 2n\)"):
        PriorMap(np.zeros((2, 2)), np.eye(3), (1, 1))
    with pytest.raises(ValueError, match="1 sighting counts for 2 landmarks"):
        PriorMap(np.zeros((2, 2)), np.eye(4), (1,))


def test_the_pass_cost_counts_a_rejected_sighting_at_the_gate():
    ekf = EKFSLAM((0.0, 0.0, 0.0))
    ekf.update(0, (2.0, 0.0), Q, 0.0)
    ekf.update(0, (2.1, 0.0), Q, 1.0)  # NIS 0.1² / (0.01 + 0.01) = 0.5
    ekf.update(0, (5.0, 0.0), Q, 2.0)  # far outside the 9.21 gate: rejected
    h = ekf.history()
    assert h.outcome_mask(Outcome.REJECTED).sum() == 1
    record = pass_record(h, 9.21, np.array([0, 0, 0]), np.array([0, 1, 0]))
    assert record.cost == pytest.approx((0.5 + 9.21) / 2, abs=1e-9)
    assert record.changed == 1
    assert pass_record(h, 9.21, np.array([0, 0, 0])).changed == -1
