"""The nearest-neighbour association's inner loop, compiled (`ekfslam.core.filter.associating`).

Apart from `ekfslam.core.filter.kernels` because it is the association's, not the filter's step;
like them it is plain Python over floats and arrays, compiled by numba with ``cache=True``, the
cache keyed on this file's source only: its constant is written here and checked against
`ekfslam.core.models` on import.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ekfslam.core import models

MIN_RANGE_SQUARED = 1e-12  # m²: closer than this, a landmark cannot be linearised
if models.MIN_RANGE_SQUARED != MIN_RANGE_SQUARED:
    raise ImportError("ekfslam.core.filter.nearest's MIN_RANGE_SQUARED disagrees with models'")


@njit(cache=True)
def nearest(mu, S, d, zs, q00, q01, q11, gate, invariant, pairing, smallest):
    """Individual compatibility of m sightings zs (m, 2) against every landmark, in O(m n).

    For landmark j, ẑ_j is eq. (10) and H_j eq. (14), nonzero on (x, y, θ, m_jx, m_jy) only, so
    S_ij = H_j Σ_j H_jᵀ + Q needs just that 5x5 block Σ_j of Σ's lower triangle, and
    NIS_ij = ν_ijᵀ S_ij⁻¹ ν_ij with ν_ij = z_i - ẑ_j (eq. 13, bearing wrapped). Writes each
    sighting's smallest NIS to smallest[i] (inf: none finite) and its landmark's index to
    pairing[i] when that NIS is at most gate, else -1: `ekfslam.core.association.individual_nis`
    then `nearest_neighbour`, without building H Σ Hᵀ (ties: the lower index, as argmin).
    invariant: Σ is in invariant coordinates, where H_j's heading column is zero (`correct`).
    """
    hth = 0.0 if invariant else -1.0
    m = zs.shape[0]
    for i in range(m):
        pairing[i] = -1
        smallest[i] = math.inf
    x, y, th = mu[0], mu[1], mu[2]
    h0 = np.zeros(5)
    h1 = np.zeros(5)
    ix = np.zeros(5, dtype=np.int64)
    ix[0], ix[1], ix[2] = 0, 1, 2
    for l in range(3, d, 2):
        dx, dy = mu[l] - x, mu[l + 1] - y
        q = max(dx * dx + dy * dy, MIN_RANGE_SQUARED)
        r = math.sqrt(q)
        zb = math.atan2(dy, dx) - th
        a, b, c, e = dx / r, dy / r, dy / q, dx / q
        h0[0], h0[1], h0[2], h0[3], h0[4] = -a, -b, 0.0, a, b
        h1[0], h1[1], h1[2], h1[3], h1[4] = c, -e, hth, -c, e
        ix[3], ix[4] = l, l + 1
        p00 = p01 = p11 = 0.0
        for u in range(5):
            s0 = s1 = 0.0
            for v in range(5):
                iu, iv = ix[u], ix[v]
                w = S[iu, iv] if iv <= iu else S[iv, iu]  # the lower triangle
                s0 += w * h0[v]
                s1 += w * h1[v]
            p00 += h0[u] * s0
            p01 += h0[u] * s1
            p11 += h1[u] * s1
        s00, s01, s11 = p00 + q00, p01 + q01, p11 + q11
        det = s00 * s11 - s01 * s01
        j = (l - 3) // 2
        for i in range(m):
            v0 = zs[i, 0] - r
            v1 = (zs[i, 1] - zb + math.pi) % (2.0 * math.pi) - math.pi
            nis = (s11 * v0 * v0 - 2.0 * s01 * v0 * v1 + s00 * v1 * v1) / det
            if not (s00 > 0.0 and det > 0.0 and math.isfinite(nis)):
                nis = math.inf
            if nis < smallest[i]:
                smallest[i] = nis
                pairing[i] = j
    for i in range(m):
        if not smallest[i] <= gate:
            pairing[i] = -1
