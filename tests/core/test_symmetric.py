"""Σ kept as its upper triangle (`ekfslam.core.filter.symmetric`): every read and write agrees
with the whole matrix, as numpy and compiled."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from ekfslam.core.filter import compile as _compile  # noqa: F401  (registers the compiled forms)
from ekfslam.core.filter.symmetric import (
    diagonal_block,
    mirror,
    rows_of,
    set_rows,
    subtract_products,
)


def stored(Sigma: np.ndarray, capacity: int) -> np.ndarray:
    """Σ in storage larger than it, with its lower triangle garbage (the steps never read it)."""
    d = len(Sigma)
    out = np.full((capacity, capacity), np.nan)
    upper = np.triu_indices(d)
    out[upper] = Sigma[upper]
    return out


def spd(d: int, seed: int) -> np.ndarray:
    A = np.random.default_rng(seed).normal(size=(d, d))
    return A @ A.T + d * np.eye(d)


@pytest.mark.parametrize(("i", "k"), [(0, 3), (3, 2), (7, 2), (9, 2)])
def test_rows_and_blocks_read_from_the_upper_triangle_are_the_matrixs(i, k) -> None:
    Sigma = spd(11, i)
    S = stored(Sigma, 14)
    np.testing.assert_array_equal(rows_of(S, i, k, 11), Sigma[i : i + k])
    np.testing.assert_array_equal(diagonal_block(S, i, k), Sigma[i : i + k, i : i + k])


def test_rows_written_then_mirrored_are_the_matrix_with_those_rows() -> None:
    Sigma = spd(11, 1)
    S = stored(Sigma, 14)
    rows = np.random.default_rng(2).normal(size=(2, 11))
    rows[:, 5:7] = [[3.0, 0.5], [0.5, 2.0]]  # its own block symmetric
    set_rows(S, 5, 11, rows)
    mirror(S, 11)
    expected = Sigma.copy()
    expected[5:7], expected[:, 5:7] = rows, rows.T
    np.testing.assert_array_equal(S[:11, :11], expected)


@njit
def compiled_subtract(S, d, A, B):
    subtract_products(S, d, A, B)


@pytest.mark.parametrize("k", [1, 2, 3, 4])  # settle's 1 row, a correction's 2, invariant's 3
def test_the_compiled_subtract_products_is_numpys(k) -> None:
    d, rng = 13, np.random.default_rng(k)
    Sigma = spd(d, k)
    W = rng.normal(size=(k, d))
    expected = Sigma - W.T @ W
    for subtract in (subtract_products, compiled_subtract):
        S = stored(Sigma, d + 3)
        subtract(S, d, W, W)
        mirror(S, d)
        np.testing.assert_allclose(S[:d, :d], expected, rtol=0, atol=1e-12)
        assert np.isnan(S[d:, :]).all() and np.isnan(S[:, d:]).all()  # nothing beyond d touched
