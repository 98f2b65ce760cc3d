"""One time-stamp error per image (`AssociationConfig.time_shared`): the sightings of one time
share the pose shift u δt, so a common shift of their bearings passes and a relative one not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam.core.association import UNPAIRED, AssociationConfig, chi2_even_quantile, joint_nis
from ekfslam.core.filter.associating import AMBIGUOUS, AssociatingFilter
from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.filter.mapping import MappingFilter
from ekfslam.core.filter.predictions import Rate
from ekfslam.core.models import observation, observation_noise
from ekfslam.core.timestamp import shared_sighting_noise, sighting_noise, time_shift

Q = observation_noise(0.01, 0.01)  # σr 1 cm, σb 0.01 rad
POSE = np.zeros(3)
A = 3.0 * np.array([1.0, 0.0])
B = 3.0 * np.array([math.cos(0.05), math.sin(0.05)])  # 0.15 m from A, 0.05 rad further left
TURN = 0.5  # rad/s: with time_sigma 0.2 s, ω σt = 0.1 rad, ten times σb


def mapped(shared: bool, backend: str = "python") -> AssociatingFilter:
    """A and B mapped by a robot standing still at the origin."""
    config = AssociationConfig(method="jcbb", time_sigma=0.2, time_shared=shared)
    f = AssociatingFilter(EKFSLAM(POSE, config=FilterConfig(backend=backend)), config)
    for t in (0.0, 1.0):
        f.observe(np.array([observation(POSE, A), observation(POSE, B)]), Q, t)
    assert f.ekf.n_landmarks == 2
    return f


def image(shift_a: float, shift_b: float) -> np.ndarray:
    """A sighting of A and one of B, their bearings shifted by shift_a and shift_b rad."""
    shifts = np.array([[0.0, shift_a], [0.0, shift_b]])
    return np.array([observation(POSE, A), observation(POSE, B)]) + shifts


def test_a_relative_shift_passes_the_independent_test_and_not_the_shared_one():
    """Sighting 2 lies 0.08 rad beyond B (an unmapped cluster mate's), sighting 1 on A: pairing
    it with B shifts one bearing against the other. Each bearing alone may be 0.1 rad off, so
    the independent term passes it (joint NIS 0.63 < χ²(4) 13.28) and JCBB pairs it with B;
    one δt shifts both alike, so the shared term refuses it (NIS 25.6) and the sighting is left
    out (ambiguous: within B's own gate)."""
    zs = image(0.0, 0.08)
    gate = chi2_even_quantile(4, 0.99)
    assert gate == pytest.approx(13.28, abs=0.01)
    nis = {}
    for shared in (False, True):
        f = mapped(shared)
        Qt, _, rate = f.noises(zs, Q, TURN, (0.0, 0.0))
        nu, P = f.predicted(zs, rate)
        nis[shared] = joint_nis([(0, 0), (1, 1)], nu, P, Qt)
        assert f.observe(zs, Q, 2.0, TURN) == ([0, UNPAIRED] if shared else [0, 1])
        if shared:
            assert f.finish().decision[-1] == AMBIGUOUS
    assert nis[False] == pytest.approx(0.63, abs=0.01)
    assert nis[True] == pytest.approx(25.6, abs=0.1)
    assert nis[False] < gate < nis[True]


def test_a_common_shift_passes_the_shared_test():
    """Both bearings 0.15 rad off (1.5 ω σt), as one δt of 0.3 s does: the shared test takes
    the image at a joint NIS of 2.2 (the common shift costs what one sighting's would)."""
    zs = image(0.15, 0.15)
    f = mapped(True)
    Qt, _, rate = f.noises(zs, Q, TURN, (0.0, 0.0))
    nu, P = f.predicted(zs, rate)
    assert joint_nis([(0, 0), (1, 1)], nu, P, Qt) == pytest.approx(2.2, abs=0.1)
    assert f.observe(zs, Q, 2.0, TURN) == [0, 1]


def test_one_sighting_while_turning_has_the_independent_terms_noise():
    """For one sighting and pure turning the shared term is (ω σt)² on the bearing; driving at
    v, the range moves by -v cos b δt and the bearing by (v sin b / r - ω) δt."""
    z = observation(POSE, B)
    assert np.allclose(
        shared_sighting_noise(Q, z, (0.0, 0.0, TURN), 0.2)[0],
        sighting_noise(Q, TURN, 0.2),
        rtol=0,
        atol=1e-15,
    )
    r, b = z
    g = time_shift(z, (0.4, 0.0, TURN))
    assert g == pytest.approx([-0.4 * math.cos(b), 0.4 * math.sin(b) / r - TURN], rel=1e-12)
    moved = observation(POSE + 1e-6 * np.array([0.4, 0.0, TURN]), B)  # the pose after δt
    assert (moved - z) / 1e-6 == pytest.approx(g, rel=1e-4)


@pytest.mark.parametrize("backend", ["python", "numba"])
def test_the_filters_shared_term_is_the_readable_one(backend):
    f = mapped(True, backend)
    zs = image(0.02, -0.01)
    rate = (0.3, -0.1, 0.4)
    nu, P = f.predicted(zs, rate)
    got = f.ekf.predictions(zs, Q, Rate(np.array(rate[:2]), rate[2], 0.04))
    np.testing.assert_allclose(got.nu, nu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.P, P, rtol=1e-9, atol=1e-15)
    assert not np.allclose(P, f.predicted(zs)[1])  # the term is there


def test_the_mapping_filter_updates_with_each_sightings_share():
    """Fed a shared-term run's decisions, the mapping filter's updates use the same per-sighting
    noise as the deciding filter's: their states agree with the same motion noise."""
    zs = image(0.03, 0.03)
    f = mapped(True)
    ekf = EKFSLAM(POSE)
    f.observe(zs, Q, 2.0, TURN, (0.3, 0.0))
    log = f.finish()
    m = MappingFilter(ekf, log, 0.2, time_shared=True)
    for t in (0.0, 1.0):
        m.observe(image(0.0, 0.0), Q, t)
    m.observe(zs, Q, 2.0, TURN, (0.3, 0.0))
    m.finish()
    np.testing.assert_allclose(m.ekf.mu, f.ekf.mu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(m.ekf.Sigma, f.ekf.Sigma, rtol=0, atol=1e-12)
