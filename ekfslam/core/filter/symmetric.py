"""Σ kept as its upper triangle: how the filter's steps read and write it.

Σ is symmetric, so the steps keep only its upper triangle current: entry (i, k) with k >= i.
The only O(n²) step of the filter, the correction's Σ -= K S Kᵀ of eq. (16), then touches half
the memory, and the pose's rows Σ[r, :d] (r = 0:3, the rows the prediction's Σ[r, m] = G Σ[r, m]
and every correction's H Σ read and write) lie in it whole, contiguous in memory. What lies below
the diagonal is stale until `mirror` fills it, when Σ is handed out
(`ekfslam.core.filter.state.FilterState.Sigma`).

Everything here runs as plain numpy and compiled by numba (`ekfslam.core.filter.compile`);
`subtract_products` also has a compiled form of its own there, one pass over the triangle,
because numpy's form makes a d x d temporary.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def rows_of(Sigma: Array, i: int, k: int, d: int) -> Array:
    """Σ[i : i + k, :d] (k, d), read from the upper triangle: a new array.

    Right of the k x k diagonal block the rows themselves; left of it, the columns above it,
    transposed; inside that block, its upper triangle mirrored.
    """
    out = np.empty((k, d))
    out[:, :i] = Sigma[:i, i : i + k].T
    out[:, i : i + k] = diagonal_block(Sigma, i, k)
    out[:, i + k : d] = Sigma[i : i + k, i + k : d]
    return out


def diagonal_block(Sigma: Array, i: int, k: int) -> Array:
    """Σ[i : i + k, i : i + k] (k, k), its upper triangle mirrored: a new array (a pose's or a
    landmark's own covariance, read without its rows)."""
    out = np.empty((k, k))
    for a in range(k):
        for b in range(k):
            out[a, b] = Sigma[i + a, i + b] if b >= a else Sigma[i + b, i + a]
    return out


def set_rows(Sigma: Array, i: int, d: int, rows: Array) -> None:
    """Σ[i : i + k, :d] = rows (k, d), written into the upper triangle (and the k x k diagonal
    block whole): rows i.. right of the diagonal block, the columns above it transposed."""
    k = rows.shape[0]
    Sigma[:i, i : i + k] = rows[:, :i].T
    Sigma[i : i + k, i + k : d] = rows[:, i + k : d]
    Sigma[i : i + k, i : i + k] = rows[:, i : i + k]


def subtract_products(Sigma: Array, d: int, A: Array, B: Array) -> None:
    """Σ[:d, :d] -= Aᵀ B on the upper triangle, for A and B of shape (k, d), k small.

    With Aᵀ B symmetric this keeps Σ symmetric; the correction's K S Kᵀ is Wᵀ W, W = L⁻¹ H Σ.
    Compiled, it is one pass over the triangle with no temporary (`ekfslam.core.filter.compile`).
    """
    Sigma[:d, :d] -= np.triu(A[:, :d].T @ B[:, :d])


def mirror(Sigma: Array, d: int) -> None:
    """Copy Σ's upper triangle onto its lower one (the used d x d block), in place."""
    upper = np.triu(Sigma[:d, :d], 1)
    lower = np.tril_indices(d, -1)
    Sigma[lower] = upper.T[lower]


def block(Sigma: Array, rows: Array, columns: Array) -> Array:
    """Σ[rows][:, columns] (len(rows), len(columns)) for index arrays, read from the upper
    triangle: the few entries a step needs of a large Σ, such as a pose-and-landmark block."""
    out = np.empty((len(rows), len(columns)))
    for a in range(len(rows)):
        for b in range(len(columns)):
            i, k = rows[a], columns[b]
            out[a, b] = Sigma[i, k] if k >= i else Sigma[k, i]
    return out
