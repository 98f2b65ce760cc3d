"""JCBB's arithmetic, compiled: the joint predictions and the branch and bound (issue 16).

`ekfslam.core.association.jcbb` is the readable reference: numpy, one recursion, a fresh
Cholesky factorisation of the hypothesis' covariance at every node. Over the seed's small maps
nearly all of its time is Python's and numpy's per-call overhead, so the filter runs these
instead, which decide the same (tested against the reference on random cases):

- `predict_all`: ν, P = H Σ Hᵀ and the individual NIS of every sighting against every landmark,
  from Σ's lower triangle (as `ekfslam.core.filter.nearest.nearest`), using that each H_j is
  nonzero on the pose and landmark j only (eq. 14): P_jk needs Σ's 5x5 blocks, not H's zeros.
- `search`: the same depth-first branch and bound, with an explicit stack instead of recursion,
  and an incremental Cholesky factor: adding pair (i, j) to a hypothesis of k pairs appends two
  rows to its factor L (X = L⁻¹ B for the cross block B, then the 2x2 factor of C - Xᵀ X) and
  two entries to w = L⁻¹ ν, so a node costs O(k²) instead of O(k³), and the joint NIS is
  |w|² (eq. 13's ν stacked).

Like `ekfslam.core.filter.kernels`, plain Python over floats and arrays (``NUMBA_DISABLE_JIT=1``
runs them uncompiled), cached beside this file.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

MIN_RANGE_SQUARED = 1e-12  # m², as `ekfslam.core.models.MIN_RANGE_SQUARED` (checked in tests)


@njit(cache=True)
def predict_all(mu, S, d, zs, q00, q01, q11, invariant, vx, vy, w, s2, nu, P, nis):
    """Fill nu (m, n, 2), P (2n, 2n) and nis (m, n) for the n = (d - 3) / 2 landmarks.

    Σ is read from S's lower triangle (S[i, k], k <= i). The result is
    `AssociatingFilter.predicted` and `ekfslam.core.association.individual_nis` with each
    sighting's noise Q = [[q00, q01], [q01, q11]].
    invariant: S is the invariant filter's ξ covariance, where H's heading column is zero
    (`ekfslam.core.filter.kernels.correct`); H Σ Hᵀ is then the same as the Cartesian one's.
    vx, vy (m/s, body frame), w (rad/s), s2 (s²): the image's time-stamp error δt ~ N(0, s2),
    one per image, moves the pose the sightings were taken from by u δt, u = (R(θ) (vx, vy), w)
    (eq. 6's rate). Every prediction then shares it: P gains s2 g gᵀ, g_j = H_pose,j u (eq. 14's
    pose columns, the Cartesian ones also for the invariant filter: δt moves the true pose), so
    a joint test allows a common shift of all the image's bearings, not relative ones. s2 = 0:
    no term.
    """
    hth = 0.0 if invariant else -1.0
    n = (d - 3) // 2
    m = zs.shape[0]
    H = np.zeros((n, 2, 5))  # each landmark's rows of H on (x, y, θ, m_jx, m_jy)
    g = np.zeros(2 * n)  # H_pose,j u, in the landmark's own range and bearing (body frame)
    for j in range(n):
        l = 3 + 2 * j
        dx, dy = mu[l] - mu[0], mu[l + 1] - mu[1]
        q = max(dx * dx + dy * dy, MIN_RANGE_SQUARED)
        r = math.sqrt(q)
        zb = math.atan2(dy, dx) - mu[2]
        a, b, c, e = dx / r, dy / r, dy / q, dx / q
        H[j, 0, 0], H[j, 0, 1], H[j, 0, 3], H[j, 0, 4] = -a, -b, a, b
        H[j, 1, 0], H[j, 1, 1], H[j, 1, 2], H[j, 1, 3], H[j, 1, 4] = c, -e, hth, -c, e
        if s2 > 0.0:  # (dx, dy)·R(θ)(vx, vy) = r (vx cos b + vy sin b), b the body bearing
            cb, sb = math.cos(zb), math.sin(zb)
            g[2 * j] = -(vx * cb + vy * sb)
            g[2 * j + 1] = (vx * sb - vy * cb) / r - w
        for i in range(m):
            nu[i, j, 0] = zs[i, 0] - r
            nu[i, j, 1] = (zs[i, 1] - zb + math.pi) % (2.0 * math.pi) - math.pi
    ix = np.zeros(5, dtype=np.int64)
    kx = np.zeros(5, dtype=np.int64)
    for j in range(n):
        ix[0], ix[1], ix[2], ix[3], ix[4] = 0, 1, 2, 3 + 2 * j, 4 + 2 * j
        for k in range(j + 1):
            kx[0], kx[1], kx[2], kx[3], kx[4] = 0, 1, 2, 3 + 2 * k, 4 + 2 * k
            for a in range(2):
                for b in range(2):
                    total = 0.0
                    for u in range(5):
                        hu = H[j, a, u]
                        if hu == 0.0:
                            continue
                        iu = ix[u]
                        s = 0.0
                        for v in range(5):
                            iv = kx[v]
                            w = S[iu, iv] if iv <= iu else S[iv, iu]
                            s += w * H[k, b, v]
                        total += hu * s
                    total += s2 * g[2 * j + a] * g[2 * k + b]
                    P[2 * j + a, 2 * k + b] = total
                    P[2 * k + b, 2 * j + a] = total
    for j in range(n):
        p00, p01, p11 = P[2 * j, 2 * j], P[2 * j, 2 * j + 1], P[2 * j + 1, 2 * j + 1]
        s00, s01, s11 = p00 + q00, p01 + q01, p11 + q11
        det = s00 * s11 - s01 * s01
        for i in range(m):
            x, y = nu[i, j, 0], nu[i, j, 1]
            value = math.inf
            if s00 > 0.0 and det > 0.0:
                value = (s11 * x * x - 2.0 * s01 * x * y + s00 * y * y) / det
                if not math.isfinite(value):
                    value = math.inf
            nis[i, j] = value


@njit(cache=True)
def _extend(L, w, k, pair_land, i, j, nu, P, Q, X):
    """Append pair (i, j) to the factor L (2k x 2k) and w of the current k pairs: returns the
    joint NIS's increase, inf when the new covariance is not positive definite."""
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


@njit(cache=True)
def search(nu, P, Qs, nis, gate, chi2, budget, pairing, unclaimed):
    """`ekfslam.core.association.jcbb`'s search over nis (m, n); chi2[k]: the joint gate of k
    pairs (chi2[0] unused). Writes the best pairing (m,), -1 for unpaired, and each sighting's
    smallest NIS over the landmarks the pairing left free (inf: none) to unclaimed (m,);
    returns (joint NIS, nodes, budget hit)."""
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
    pair_land = np.zeros(m, dtype=np.int64)
    L = np.zeros((2 * m, 2 * m))
    w = np.zeros(2 * m)
    X = np.zeros((2 * m, 2))
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
                d2 = value[i] + _extend(L, w, k, pair_land, i, j, nu, P, Qs, X)
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
