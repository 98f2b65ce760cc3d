"""JCBB's branch and bound, the search that `ekfslam.core.association.jcbb` states readably.

`ekfslam.core.association.jcbb` is the readable reference: numpy, one recursion, a fresh
Cholesky factorisation of the hypothesis' covariance at every node. This is the same depth-first
branch and bound as the filter runs it (compiled with the steps, `ekfslam.core.filter.backend`),
deciding the same (tested against the reference on random cases): an explicit stack instead of
recursion, and an incremental Cholesky factor. Adding pair (i, j) to a hypothesis of k pairs
appends two rows to its factor L (X = L⁻¹ B for the cross block B, then the 2x2 factor of
C - Xᵀ X) and two entries to w = L⁻¹ ν, so a node costs O(k²) instead of O(k³), and the joint NIS
is |w|² (eq. 13's ν stacked). The predictions it searches over are
`ekfslam.core.filter.predictions.predict_all`'s.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.filter.predictions import Predicted

Array = NDArray[np.float64]


class Limits(NamedTuple):
    """What bounds the search: gate, the individual NIS a pair may have; chi2 (m + 1,), the
    joint gate of k pairs at chi2[k] (chi2[0] unused); budget, the nodes it may visit."""

    gate: float
    chi2: Array
    budget: int


class Factor(NamedTuple):
    """The current hypothesis' joint covariance, factored as it grows: L (2m, 2m) its Cholesky
    factor, w (2m,) = L⁻¹ ν, X (2m, 2) scratch, and pair_land (m,) the landmark of each pair."""

    L: Array
    w: Array
    X: Array
    pair_land: NDArray[np.int64]


def _extend(factor: Factor, k: int, i: int, j: int, predicted: Predicted, Qs: Array) -> float:
    """Append pair (i, j) to the factor of the current k pairs: returns the joint NIS's
    increase, inf when the new covariance is not positive definite."""
    L, w, X, pair_land = factor
    nu, P, _ = predicted
    Q = Qs
    kk = 2 * k
    for c in range(2):  # X = L⁻¹ B, B the cross covariance of the old pairs with landmark j
        for r in range(kk):
            s = P[2 * pair_land[r // 2] + r % 2, 2 * j + c]
            for t in range(r):
                s -= L[r, t] * X[t, c]
            X[r, c] = s / L[r, r]
    c00 = P[2 * j, 2 * j] + Q[i, 0, 0]
    c01 = P[2 * j, 2 * j + 1] + Q[i, 0, 1]
    c11 = P[2 * j + 1, 2 * j + 1] + Q[i, 1, 1]
    t0, t1 = nu[i, j, 0], nu[i, j, 1]
    for r in range(kk):
        c00 -= X[r, 0] * X[r, 0]
        c01 -= X[r, 0] * X[r, 1]
        c11 -= X[r, 1] * X[r, 1]
        t0 -= X[r, 0] * w[r]
        t1 -= X[r, 1] * w[r]
    if not c00 > 0.0:
        return math.inf
    m00 = math.sqrt(c00)
    m10 = c01 / m00
    rest = c11 - m10 * m10
    if not rest > 0.0:
        return math.inf
    m11 = math.sqrt(rest)
    for r in range(kk):
        L[kk, r] = X[r, 0]
        L[kk + 1, r] = X[r, 1]
    L[kk, kk], L[kk + 1, kk], L[kk + 1, kk + 1] = m00, m10, m11
    w0 = t0 / m00
    w1 = (t1 - m10 * w0) / m11
    w[kk], w[kk + 1] = w0, w1
    return w0 * w0 + w1 * w1


def search(
    predicted: Predicted, Qs: Array, limits: Limits, pairing: Array, unclaimed: Array
) -> tuple[float, int, bool]:
    """`ekfslam.core.association.jcbb`'s search over `predicted` (m sightings, n landmarks), Qs
    (m, 2, 2) each sighting's noise. Writes the best pairing (m,), -1 for unpaired, and each
    sighting's smallest NIS over the landmarks the pairing left free (inf: none) to unclaimed
    (m,); returns (joint NIS, nodes, budget hit)."""
    nis, (gate, chi2, budget) = predicted[2], limits
    m, n = nis.shape
    opts = np.empty((m, n), dtype=np.int64)
    nopt = np.zeros(m, dtype=np.int64)
    for i in range(m):
        order = np.argsort(nis[i], kind="mergesort")  # stable, as the reference's
        for j in order:
            if nis[i, j] <= gate:
                opts[i, nopt[i]] = j
                nopt[i] += 1
    could = np.zeros(m + 1, dtype=np.int64)
    for i in range(m - 1, -1, -1):
        could[i] = could[i + 1] + (nopt[i] > 0)
    for i in range(m):
        pairing[i] = -1
    best_count, best_value = 0, 0.0
    current = np.full(m, -1, dtype=np.int64)  # landmark of sighting i on the current path
    used = np.zeros(n, dtype=np.bool_)
    factor = Factor(
        np.zeros((2 * m, 2 * m)), np.zeros(2 * m), np.zeros((2 * m, 2)), np.zeros(m, np.int64)
    )
    pair_land = factor[3]
    value = np.zeros(m + 1)  # the joint NIS of the current pairs on entering depth i
    stage = np.zeros(m + 1, dtype=np.int64)  # 0 entered, 1 trying landmarks, 2 tried unpaired
    pos = np.zeros(m + 1, dtype=np.int64)
    k, nodes, hit, depth = 0, 0, False, 0
    while depth >= 0:
        i = depth
        pop = False
        if stage[i] == 0:
            if i == m:
                if k > best_count or (k == best_count and value[i] < best_value):
                    best_count, best_value = k, value[i]
                    for s in range(m):
                        pairing[s] = current[s]
                pop = True
            elif not (
                k + could[i] > best_count or (k + could[i] == best_count and value[i] < best_value)
            ):
                pop = True
            else:
                stage[i], pos[i] = 1, 0
        if not pop and stage[i] == 1:
            down = False
            while pos[i] < nopt[i]:
                j = opts[i, pos[i]]
                pos[i] += 1
                if used[j]:
                    continue
                if nodes >= budget:
                    hit, pop = True, True
                    break
                nodes += 1
                d2 = value[i] + _extend(factor, k, i, j, predicted, Qs)
                if d2 <= chi2[k + 1]:
                    used[j] = True
                    pair_land[k], current[i] = j, j
                    k += 1
                    value[i + 1], stage[i + 1], depth = d2, 0, i + 1
                    down = True
                    break
            if down:
                continue
            if not pop:
                stage[i] = 2
                most = k + could[i + 1]
                if most > best_count or (most == best_count and value[i] < best_value):
                    value[i + 1], stage[i + 1], depth = value[i], 0, i + 1
                    continue
                pop = True
        if stage[i] == 2:
            pop = True
        if pop:
            depth -= 1
            if depth >= 0 and stage[depth] == 1:  # back from a pair: undo it
                k -= 1
                used[pair_land[k]] = False
                current[depth] = -1
    for j in range(n):
        used[j] = False
    for s in range(m):
        if pairing[s] >= 0:
            used[pairing[s]] = True
    for s in range(m):
        unclaimed[s] = math.inf
        for j in range(n):
            if not used[j] and nis[s, j] < unclaimed[s]:
                unclaimed[s] = nis[s, j]
    return best_value, nodes, hit


_LOG_2PI = math.log(2.0 * math.pi)


def option_likelihoods(
    predicted: Predicted, Qs: Array, options: NDArray[np.int64], out: Array, free: Array
) -> None:
    """Score each of a hypothesis' options for ``mht`` (`ekfslam.core.filter.mht`), one factor
    grown pair by pair as the search grows it (`_extend`).

    options (B, m): each sighting's landmark index, negative for none. Writes out (B, 2): the
    joint Gaussian log-likelihood of the option's pairs, -½(νᵀS⁻¹ν + log det 2πS) with S the
    pairs' joint covariance plus each sighting's Qs[i] (eq. 13's ν stacked), and its joint NIS
    νᵀS⁻¹ν ((0, 0) for no pair; (-inf, inf) when S is not positive definite); and free (B, m):
    each sighting's smallest NIS over the landmarks the option leaves free (inf: none), what the
    "threshold" new-landmark rule reads (`ekfslam.core.filter.associating.free_nis`).
    """
    nis = predicted[2]
    m, n = nis.shape
    factor = Factor(
        np.zeros((2 * m, 2 * m)), np.zeros(2 * m), np.zeros((2 * m, 2)), np.zeros(m, np.int64)
    )
    L, pair_land = factor[0], factor[3]
    used = np.zeros(n, dtype=np.bool_)
    for b in range(options.shape[0]):
        k, d2, log_diagonal, positive = 0, 0.0, 0.0, True
        for i in range(m):
            j = options[b, i]
            if j < 0:
                continue
            step = _extend(factor, k, i, j, predicted, Qs)
            if not step < math.inf:
                positive = False
                break
            d2 += step
            log_diagonal += math.log(L[2 * k, 2 * k]) + math.log(L[2 * k + 1, 2 * k + 1])
            pair_land[k] = j
            k += 1
        if positive:
            out[b, 0] = -0.5 * d2 - log_diagonal - k * _LOG_2PI
            out[b, 1] = d2
        else:
            out[b, 0], out[b, 1] = -math.inf, math.inf
        for j in range(n):
            used[j] = False
        for i in range(m):
            if options[b, i] >= 0:
                used[options[b, i]] = True
        for i in range(m):
            smallest = math.inf
            for j in range(n):
                if not used[j] and nis[i, j] < smallest:
                    smallest = nis[i, j]
            free[b, i] = smallest
