"""The filter's JCBB (`ekfslam.core.filter.jcbb_search`, as Python and compiled) decides as the
readable reference (`ekfslam.core.association.jcbb`), over the filter's predictions."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ekfslam.core.association import AssociationConfig, individual_nis, jcbb
from ekfslam.core.filter import mht
from ekfslam.core.filter.associating import AssociatingFilter, free_nis
from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.models import observation, observation_noise


def random_case(seed: int, budget: int = 10_000, backend: str = "python"):
    """A map of close pairs and lone tags, a drifted pose, sightings of some, and strays."""
    rng = np.random.default_rng(seed)
    ekf = EKFSLAM(np.zeros(3), np.diag([0.04, 0.04, 0.01]), FilterConfig(backend=backend))
    lone = rng.uniform(-4.0, 4.0, size=(6, 2))
    pairs = rng.uniform(-4.0, 4.0, size=(3, 2))
    marks = np.vstack([lone, pairs, pairs + rng.normal(0.0, 0.2, pairs.shape)])
    Q = observation_noise(0.05, 0.03)
    for j, p in enumerate(marks):
        ekf.update(j, observation(np.zeros(3), p), Q)
    ekf.predict(np.array([0.1, 0.0, 0.05]), np.diag([1e-3, 1e-3, 4e-3]))
    seen = rng.choice(len(marks), size=rng.integers(1, 9), replace=False)
    points = np.vstack([marks[seen], rng.uniform(-5.0, 5.0, (rng.integers(0, 3), 2))])
    zs = np.array([observation(ekf.pose, p) for p in points])
    zs += rng.normal(0.0, [0.05, 0.03], zs.shape)
    f = AssociatingFilter(ekf, AssociationConfig(method="jcbb", node_budget=budget))
    return f, zs, Q


@pytest.mark.parametrize("backend", ["python", "numba"])
@pytest.mark.parametrize("budget", [10_000, 5])
def test_the_filters_jcbb_decides_as_the_reference(budget, backend):
    hits = 0
    for seed in range(40):
        f, zs, Q = random_case(seed, budget, backend)
        nu, P = f.predicted(zs)
        Qs = np.broadcast_to(Q, (len(zs), 2, 2))
        want = jcbb(nu, P, Qs, f.config.gate, f.config.joint_probability, budget)
        got, unclaimed = f._jcbb(zs, Q)
        assert got.pairing.tolist() == want.pairing.tolist(), seed
        assert got.nodes == want.nodes and got.budget_hit == want.budget_hit, seed
        assert got.joint_nis == pytest.approx(want.joint_nis, rel=1e-9, abs=1e-12)
        nis = individual_nis(nu, P, Qs)
        free = np.ones(nis.shape[1], dtype=bool)
        free[want.pairing[want.pairing >= 0]] = False
        smallest = nis[:, free].min(axis=1) if free.any() else np.full(len(zs), np.inf)
        f.config = dataclasses.replace(f.config, new_rule="threshold")  # the kernel's own figure
        np.testing.assert_allclose(f._jcbb(zs, Q)[1], smallest, rtol=1e-9, atol=1e-12)
        by_density = free_nis(
            nis, P, Q, want.pairing, dataclasses.replace(f.config, new_rule="density")
        )
        np.testing.assert_allclose(unclaimed, by_density, rtol=1e-9, atol=1e-12)
        hits += got.budget_hit
    assert (hits > 0) == (budget == 5)  # the small budget is reached, the default not


@pytest.mark.parametrize("backend", ["python", "numba"])
def test_the_filters_predictions_are_h_sigma_ht(backend):
    f, zs, Q = random_case(7, backend=backend)
    nu, P = f.predicted(zs)
    got = f.ekf.predictions(zs, Q)
    np.testing.assert_allclose(got.nu, nu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.P, P, rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("backend", ["python", "numba"])
def test_the_option_likelihoods_are_mhts_joint_gaussian_and_free_nis(backend):
    """Issue 39: mht scores all of a hypothesis' options in one compiled call; each is the
    readable `mht.log_likelihood` (the stacked pairs' covariance factored by numpy) and
    `free_nis` with the threshold rule, on random options of random cases."""
    rng = np.random.default_rng(3)
    for seed in range(20):
        f, zs, Q = random_case(seed, backend=backend)
        predicted = f._predict_all(zs, Q)
        nu, P, nis = predicted
        m, n = nis.shape
        options = rng.integers(-2, n, size=(6, m))
        for row in options:  # each landmark at most once in an option, as mht's options are
            _, first = np.unique(row, return_index=True)
            keep = np.zeros(m, dtype=bool)
            keep[first] = True
            row[~keep & (row >= 0)] = -1
        options[0] = -1  # no pair at all
        Qs = np.empty((m, 2, 2))
        Qs[:] = Q
        scores, free = np.empty((len(options), 2)), np.empty((len(options), m))
        f.ekf.steps.option_likelihoods(tuple(predicted), Qs, options, scores, free)
        threshold = dataclasses.replace(f.config, new_rule="threshold")
        for b, option in enumerate(options):
            pairs = [(i, int(j)) for i, j in enumerate(option) if j >= 0]
            ll, d2 = mht.log_likelihood(pairs, nu, P, Q)
            assert scores[b, 0] == pytest.approx(ll, rel=1e-10, abs=1e-10), (seed, b)
            assert scores[b, 1] == pytest.approx(d2, rel=1e-10, abs=1e-10), (seed, b)
            want = free_nis(nis, P, Q, option, threshold)
            np.testing.assert_array_equal(free[b], want)
    assert tuple(scores[0]) == (0.0, 0.0)
