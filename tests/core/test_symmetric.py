"""Σ kept whole and exactly symmetric (`ekfslam.core.filter.symmetric`): every read and write
agrees with the whole matrix, as numpy and compiled; and any read of Σ a user can make is current
after the filter's steps (a kept view read 2.5e-3 stale values below the diagonal when only the
upper triangle was kept)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from ekfslam.core.filter import compile as _compile  # noqa: F401  (registers the compiled forms)
from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.filter.symmetric import (
    diagonal_block,
    rows_of,
    set_block,
    set_rows,
    subtract_products,
)
from ekfslam.teaching.reference import LiteralEKFSLAM


def stored(Sigma: np.ndarray, capacity: int) -> np.ndarray:
    """Σ in storage larger than it, NaN beyond d (the steps never touch it)."""
    d = len(Sigma)
    out = np.full((capacity, capacity), np.nan)
    out[:d, :d] = Sigma
    return out


def spd(d: int, seed: int) -> np.ndarray:
    A = np.random.default_rng(seed).normal(size=(d, d))
    return A @ A.T + d * np.eye(d)


@pytest.mark.parametrize(("i", "k"), [(0, 3), (3, 2), (7, 2), (9, 2)])
def test_rows_and_blocks_are_the_matrixs(i, k) -> None:
    Sigma = spd(11, i)
    S = stored(Sigma, 14)
    np.testing.assert_array_equal(rows_of(S, i, k, 11), Sigma[i : i + k])
    np.testing.assert_array_equal(diagonal_block(S, i, k), Sigma[i : i + k, i : i + k])


def test_rows_written_are_the_matrix_with_those_rows_and_columns() -> None:
    Sigma = spd(11, 1)
    S = stored(Sigma, 14)
    rows = np.random.default_rng(2).normal(size=(2, 11))
    rows[:, 5:7] = [[3.0, 0.5], [0.5, 2.0]]  # its own block symmetric
    set_rows(S, 5, 11, rows)
    expected = Sigma.copy()
    expected[5:7], expected[:, 5:7] = rows, rows.T
    np.testing.assert_array_equal(S[:11, :11], expected)
    assert np.isnan(S[11:, :]).all() and np.isnan(S[:, 11:]).all()


def test_a_block_is_set_from_its_upper_triangle_exactly_symmetric() -> None:
    S = np.zeros((5, 5))
    P = np.array([[1.0, 2.0, 3.0], [2.0 + 1e-15, 4.0, 5.0], [3.0, 5.0 - 1e-15, 6.0]])
    set_block(S, 1, P)
    np.testing.assert_array_equal(S, S.T)
    np.testing.assert_array_equal(S[1:4, 1:4], np.triu(P) + np.triu(P, 1).T)


@njit
def compiled_subtract(S, d, A, B):
    subtract_products(S, d, A, B)


@pytest.mark.parametrize("k", [1, 2, 3, 4])  # settle's 1 row, a correction's 2, invariant's 3
def test_the_compiled_subtract_products_is_numpys_and_exactly_symmetric(k) -> None:
    d, rng = 13, np.random.default_rng(k)
    Sigma = spd(d, k)
    W = rng.normal(size=(k, d))
    expected = Sigma - W.T @ W
    for subtract in (subtract_products, compiled_subtract):
        S = stored(Sigma, d + 3)
        subtract(S, d, W, W)
        np.testing.assert_allclose(S[:d, :d], expected, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(S[:d, :d], S[:d, :d].T)
        assert np.isnan(S[d:, :]).all() and np.isnan(S[:, d:]).all()  # nothing beyond d touched


@pytest.mark.parametrize("linearization", ["standard", "fej", "invariant"])
@pytest.mark.parametrize("backend", ["python", "numba"])
def test_every_read_of_sigma_is_current_after_steps(linearization, backend) -> None:
    """A view of Σ kept from before, its rows, its columns, a landmark's block and the pose's all
    read the values Σ has now: against a fresh read and against the literal reference."""
    config = FilterConfig(linearization=linearization, backend=backend, gate=None)
    f = EKFSLAM(np.zeros(3), np.diag([0.01, 0.01, 0.001]), config=config)
    Q, M = np.diag([0.01, 0.001]), np.diag([1e-3, 1e-4, 1e-4])
    for i, (r, b) in enumerate([(2.0, 0.3), (3.0, -1.0), (2.5, 2.0)]):
        f.update(i, np.array([r, b]), Q, 0.0)
    kept = f.Sigma  # a view, kept across the steps below
    for t in range(1, 6):
        f.predict_many(np.array([[0.1, 0.0, 0.05]]), np.ones(1), np.array([float(t)]), M=M)
        for i, (r, b) in enumerate([(2.0, 0.3), (3.0, -1.0), (2.5, 2.0)]):
            f.update(i, np.array([r - 0.05 * t, b - 0.03 * t]), Q, float(t))
    seen = kept.copy()  # what the kept view reads now, before Σ is read again
    now = f.Sigma
    if linearization == "invariant":  # it hands out T P Tᵀ, a new array each read
        np.testing.assert_allclose(now, now.T, rtol=0, atol=1e-15)
        np.testing.assert_array_equal(f.invariant_covariance, f.invariant_covariance.T)
    else:
        np.testing.assert_array_equal(now, now.T)
        np.testing.assert_array_equal(seen, now)
    for j in range(3):
        L = slice(3 + 2 * j, 5 + 2 * j)
        np.testing.assert_allclose(now[L, :], now[:, L].T, rtol=0, atol=1e-15)
        _, P = f.landmark(j)
        np.testing.assert_allclose(P, now[L, L], rtol=0, atol=1e-15)
    np.testing.assert_allclose(f.pose_covariance, now[:3, :3], rtol=0, atol=1e-15)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    updates=st.lists(
        st.tuples(st.integers(0, 3), st.floats(1.0, 4.0), st.floats(-3, 3)), min_size=3, max_size=12
    ),
)
def test_sigma_matches_the_literal_reference_in_both_halves(seed, updates) -> None:
    """Any row and any column of Σ, after generated sightings, is the literal F_x filter's."""
    config = FilterConfig(gate=None, reinit_after=None, backend="python")
    f = EKFSLAM(np.zeros(3), config=config)
    ref = LiteralEKFSLAM(np.zeros(3), config=config)
    Q = np.diag([0.02, 0.002])
    rng = np.random.default_rng(seed)
    for i, r, b in updates:
        u = rng.normal(0, 0.05, 3)
        R = np.diag([1e-3, 1e-3, 1e-4])
        f.predict(u, R)
        ref.predict(u, R)
        f.update(i, np.array([r, b]), Q)
        ref.update(i, np.array([r, b]), Q)
    np.testing.assert_allclose(f.Sigma, ref.Sigma, rtol=0, atol=1e-9)
