"""Σ kept whole and symmetric: how the filter's steps read and write it.

Both triangles of Σ are current after every step, so any read of Σ, a kept view, ``Sigma[L, :]``
or ``Sigma[:, L]``, gives the current value. The steps keep it exactly symmetric (entry (i, k)
and entry (k, i) are the same float): a row block is written with its transpose
(`set_rows`), a diagonal block from its upper triangle mirrored (`set_block`), and the
correction's Σ -= K S Kᵀ of eq. (16) as Σ -= Wᵀ W, whose (i, k) and (k, i) are the same
products summed in the same order (`subtract_products`).

The pose's rows Σ[r, :d] (r = 0:3, read and written by the prediction's Σ[r, m] = G Σ[r, m] and
every correction's H Σ) are contiguous in memory.

Everything here runs as plain numpy and compiled by numba (`ekfslam.core.filter.compile`);
`subtract_products` also has a compiled form of its own there, one pass over Σ with no
temporary, because numpy's form makes a d x d one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def rows_of(Sigma: Array, i: int, k: int, d: int) -> Array:
    """Σ[i : i + k, :d] (k, d): a view, valid until the next step changes Σ."""
    return Sigma[i : i + k, :d]


def diagonal_block(Sigma: Array, i: int, k: int) -> Array:
    """Σ[i : i + k, i : i + k] (k, k), a new array (a pose's or a landmark's own covariance)."""
    return Sigma[i : i + k, i : i + k].copy()


def set_block(Sigma: Array, i: int, P: Array) -> None:
    """Σ[i : i + k, i : i + k] = P (k, k), from P's upper triangle mirrored (exactly symmetric)."""
    k = P.shape[0]
    for a in range(k):
        for b in range(a, k):
            Sigma[i + a, i + b] = P[a, b]
            Sigma[i + b, i + a] = P[a, b]


def set_rows(Sigma: Array, i: int, d: int, rows: Array) -> None:
    """Σ[i : i + k, :d] = rows (k, d), and Σ[:d, i : i + k] = rowsᵀ; the k x k diagonal block
    from its upper triangle (`set_block`)."""
    k = rows.shape[0]
    Sigma[i : i + k, :d] = rows
    Sigma[:d, i : i + k] = rows.T
    set_block(Sigma, i, rows[:, i : i + k])


def subtract_products(Sigma: Array, d: int, A: Array, B: Array) -> None:
    """Σ[:d, :d] -= Aᵀ B, for A and B of shape (k, d), k small, keeping Σ exactly symmetric.

    The correction's K S Kᵀ is Wᵀ W (W = C⁻¹ H Σ, A = B = W); the invariant filter's owed
    ρ v vᵀ is added as A = -u, B = u with u = √ρ v. Aᵀ B is then symmetric in exact
    arithmetic and A[a, i] B[a, k] = ±(the same two floats' product) as A[a, k] B[a, i], so
    the compiled form (`ekfslam.core.filter.compile`), one pass over all of Σ, keeps (i, k)
    and (k, i) the same float. This numpy form does too: Wᵀ W is BLAS's symmetric product
    (numpy sees one operand the other's transpose), and otherwise the upper triangle of Aᵀ B is
    mirrored.
    """
    if A is B:
        W = A[:, :d]
        Sigma[:d, :d] -= W.T @ W
    else:
        P = np.triu(A[:, :d].T @ B[:, :d])
        Sigma[:d, :d] -= P + np.triu(P, 1).T


def block(Sigma: Array, rows: Array, columns: Array) -> Array:
    """Σ[rows][:, columns] (len(rows), len(columns)) for index arrays: the few entries a step
    needs of a large Σ, such as a pose-and-landmark block."""
    out = np.empty((len(rows), len(columns)))
    for a in range(len(rows)):
        for b in range(len(columns)):
            out[a, b] = Sigma[rows[a], columns[b]]
    return out
