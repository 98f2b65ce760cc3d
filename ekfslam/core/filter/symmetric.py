"""Σ kept as its lower triangle: how the filter's steps read and write it.

Σ is symmetric, so the steps keep only its lower triangle current: entry (i, k) with k <= i.
The only O(n²) step of the filter, the correction's Σ -= K S Kᵀ of eq. (16), then touches half
the memory, and the prediction's Σ[r, m] = G Σ[r, m] is written once, as its transpose Σ[m, r]
(which is in the lower triangle). What lies above the diagonal is stale until `mirror` fills it,
when Σ is handed out (`ekfslam.core.filter.state.FilterState.Sigma`).

Everything here runs as plain numpy and compiled by numba (`ekfslam.core.filter.compile`);
`subtract_products` also has a compiled form of its own there, one pass over the triangle,
because numpy's form makes a d x d temporary.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def rows_of(Sigma: Array, i: int, k: int, d: int) -> Array:
    """Σ[i : i + k, :d] (k, d), read from the lower triangle: a new array.

    Left of row i's diagonal the rows themselves; right of the k x k diagonal block, the
    columns below it, transposed; inside that block, its lower triangle mirrored.
    """
    out = np.empty((k, d))
    out[:, :i] = Sigma[i : i + k, :i]
    out[:, i + k : d] = Sigma[i + k : d, i : i + k].T
    for a in range(k):
        for b in range(k):
            out[a, i + b] = Sigma[i + a, i + b] if b <= a else Sigma[i + b, i + a]
    return out


def set_rows(Sigma: Array, i: int, d: int, rows: Array) -> None:
    """Σ[i : i + k, :d] = rows (k, d), written into the lower triangle (and the k x k diagonal
    block whole): rows i.. left of the diagonal block, the columns below it transposed."""
    k = rows.shape[0]
    Sigma[i : i + k, :i] = rows[:, :i]
    Sigma[i + k : d, i : i + k] = rows[:, i + k : d].T
    Sigma[i : i + k, i : i + k] = rows[:, i : i + k]


def subtract_products(Sigma: Array, d: int, A: Array, B: Array) -> None:
    """Σ[:d, :d] -= Aᵀ B on the lower triangle, for A and B of shape (k, d), k small.

    With Aᵀ B symmetric this keeps Σ symmetric; the correction's K S Kᵀ is Wᵀ W, W = L⁻¹ H Σ.
    Compiled, it is one pass over the triangle with no temporary (`ekfslam.core.filter.compile`).
    """
    Sigma[:d, :d] -= np.tril(A[:, :d].T @ B[:, :d])


def mirror(Sigma: Array, d: int) -> None:
    """Copy Σ's lower triangle onto its upper one (the used d x d block), in place."""
    lower = np.tril(Sigma[:d, :d], -1)
    upper = np.triu_indices(d, 1)
    Sigma[upper] = lower.T[upper]


def block(Sigma: Array, rows: Array, columns: Array) -> Array:
    """Σ[rows][:, columns] (len(rows), len(columns)) for index arrays, read from the lower
    triangle: the few entries a step needs of a large Σ, such as a pose-and-landmark block."""
    out = np.empty((len(rows), len(columns)))
    for a in range(len(rows)):
        for b in range(len(columns)):
            i, k = rows[a], columns[b]
            out[a, b] = Sigma[i, k] if k <= i else Sigma[k, i]
    return out
