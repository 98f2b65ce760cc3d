"""Association decisions on constructed cases: nn, jcbb, the χ² quantiles, the confusion."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam.core.association import (
    UNPAIRED,
    AssociationConfig,
    chi2_even_quantile,
    confusion,
    individual_nis,
    jcbb,
    joint_nis,
    nearest_neighbour,
)
from ekfslam.errors import ConfigError

GATE = -2.0 * math.log1p(-0.99)  # χ²(2) 99%: 9.21


def shared_pose_error_case():
    """Two landmarks A, B and two sightings, where a shared pose error fools NN.

    Range only matters (bearing innovations are 0, their blocks uncorrelated). Predicted ranges
    ẑ_A = 0, ẑ_B = 1; the pose error adds 0.8 to both, so s1 (of A) reads 0.8, s2 (of B) 1.8.
    The range covariance is mostly that shared pose error: P_AA = P_BB = 0.25, P_AB = 0.24;
    Q = 0.01, so each individual S = 0.26.

    NN, by hand: s1 -> A: 0.8² / 0.26 = 2.46, s1 -> B: 0.2² / 0.26 = 0.154 (chosen: wrong);
    s2 -> A: 1.8² / 0.26 = 12.46 > 9.21, s2 -> B: 0.8² / 0.26 = 2.46 (chosen). Both take B.

    JCBB, by hand: the one pairing of both sightings with every pair individually compatible is
    (s1 -> A, s2 -> B) (s2 -> A fails the gate), with ν = (0.8, 0.8) and
    S = [[0.26, 0.24], [0.24, 0.26]]. ν lies along (1, 1), S's eigenvector of eigenvalue
    0.26 + 0.24 = 0.5, so the joint NIS is |ν|² / 0.5 = 1.28 / 0.5 = 2.56 <= χ²(4) 99% = 13.28:
    jointly compatible, and JCBB takes it (right). (s1 -> B alone pairs one sighting only.)
    """
    # rows of P: (A range, A bearing, B range, B bearing)
    P = np.array(
        [
            [0.25, 0.0, 0.24, 0.0],
            [0.0, 0.01, 0.0, 0.0],
            [0.24, 0.0, 0.25, 0.0],
            [0.0, 0.0, 0.0, 0.01],
        ]
    )
    zhat = np.array([[0.0, 0.0], [1.0, 0.0]])  # (landmark, (r, φ))
    z = np.array([[0.8, 0.0], [1.8, 0.0]])
    nu = z[:, None, :] - zhat[None, :, :]
    Q = np.broadcast_to(np.diag([0.01, 0.01]), (2, 2, 2))
    return nu, P, Q


def test_nn_is_fooled_by_a_shared_pose_error_and_jcbb_is_not():
    nu, P, Q = shared_pose_error_case()
    nis = individual_nis(nu, P, Q)
    np.testing.assert_allclose(nis, [[0.64 / 0.26, 0.04 / 0.26], [3.24 / 0.26, 0.64 / 0.26]])
    assert nearest_neighbour(nis, GATE).tolist() == [1, 1]  # s1 wrongly on B
    found = jcbb(nu, P, Q, GATE)
    assert found.pairing.tolist() == [0, 1]
    assert found.joint_nis == pytest.approx(2.56)
    assert found.joint_nis == pytest.approx(joint_nis([(0, 0), (1, 1)], nu, P, Q))
    assert chi2_even_quantile(4, 0.99) == pytest.approx(13.2767, abs=1e-4)
    assert not found.budget_hit


def test_jcbb_stops_at_its_node_budget_and_says_so():
    nu, P, Q = shared_pose_error_case()
    found = jcbb(nu, P, Q, GATE, node_budget=1)
    assert found.budget_hit and found.nodes == 1
    assert len(found.pairing) == 2  # still a pairing: the best one found in budget


def test_chi2_quantiles_match_the_closed_forms():
    assert chi2_even_quantile(2, 0.99) == pytest.approx(GATE)
    assert chi2_even_quantile(6, 0.95) == pytest.approx(12.5916, abs=1e-4)


def test_each_landmark_is_used_once_by_jcbb():
    """Two sightings of one landmark at one time: one is paired, the other left unpaired."""
    nu = np.array([[[0.01, 0.0]], [[-0.01, 0.0]]])
    P = np.eye(2) * 0.01
    Q = np.broadcast_to(np.eye(2) * 0.01, (2, 2, 2))
    assert sorted(jcbb(nu, P, Q, GATE).pairing.tolist()) == [UNPAIRED, 0]
    assert nearest_neighbour(individual_nis(nu, P, Q), GATE).tolist() == [0, 0]


def test_confusion_maps_by_majority_and_counts_wrong_and_missed():
    # estimated 0 is true 7 (3 of 4 sightings), estimated 1 is true 9; one miss of 7
    est = [UNPAIRED, 0, 0, 1, 0, UNPAIRED, 0]
    true = [7, 7, 7, 9, 9, 7, 7]
    c = confusion(est, true)
    assert c.mapping == {0: 7, 1: 9}
    assert (c.correct, c.wrong, c.missed) == (4, 1, 1)  # the first 7 founded it: not missed
    assert c.correct_fraction == pytest.approx(4 / 6)


def test_config_refuses_a_new_landmark_threshold_inside_the_gate():
    with pytest.raises(ConfigError):
        AssociationConfig(method="nn", gate=9.0, new_landmark=5.0)
    with pytest.raises(ConfigError):
        AssociationConfig(method="bogus")  # type: ignore[arg-type]


def test_config_refuses_a_negative_or_infinite_time_sigma():
    for bad in (-0.1, float("inf"), float("nan")):
        with pytest.raises(ConfigError, match="time_sigma"):
            AssociationConfig(method="jcbb", time_sigma=bad)


def test_config_refuses_an_unknown_new_landmark_rule():
    with pytest.raises(ConfigError, match="new_rule must be one of density, threshold, got 'nis'"):
        AssociationConfig(method="jcbb", new_rule="nis")  # type: ignore[arg-type]
    assert AssociationConfig().new_rule == "density"
    # each method's own founding: mht's bank already weighs "new" by the density
    assert AssociationConfig(method="jcbb").new_rule == "density"
    assert AssociationConfig(method="mht").new_rule == "threshold"
    assert AssociationConfig(method="mht", new_rule="density").new_rule == "density"
