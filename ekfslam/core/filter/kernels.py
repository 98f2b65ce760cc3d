"""The filter's inner loops, compiled: one prediction batch and one correction, in place.

`ekfslam.core.filter.ekf` decides what happens (landmark slots, gating, re-initialisation,
counting); these functions do the arithmetic on its pre-allocated storage. They are numba-compiled
because a step of the seed's small map is a few hundred flops: as numpy calls, Python's and numpy's
per-call overhead cost ten times the arithmetic (see `python -m ekfslam bench`). Compiled loops
also let the O(n²) update of eq. (16) run in one pass over Σ with no temporary.

Each function is plain Python over floats and arrays; with the environment variable
``NUMBA_DISABLE_JIT=1`` they run as such, which is how to step through them in a debugger.
The compiled code is cached beside this file (``cache=True``), so only the first import on a
machine pays the compilation (a few seconds). The cache is keyed on this file's source only:
module-level constants the kernels use are therefore written here, not imported.

Conventions: S is the (capacity, capacity) covariance storage and mu the (capacity,) mean, both
zero beyond the state's size d; l is a landmark's first index (3 + 2j). Σ is symmetric, so the
kernels keep only its lower triangle (S[i, k], k <= i) current, plus the whole 3x3 pose block:
the O(n²) update then touches half the memory. `mirror` fills the upper triangle when the
filter hands Σ out. The history's rows
are laid out as `ekfslam.core.filter.history.ROW` and `ekfslam.core.filter.history.OBS_ROW`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ekfslam.core import models
from ekfslam.core.filter import history

# Constants the compiled code bakes in. numba's cache is keyed on this file alone, so they are
# written here, and checked against the modules that own them when this module is imported.
ACCEPTED, REJECTED, REFUSED, SINGULAR = 1, 2, 3, 5  # the outcome codes `correct` returns
MIN_RANGE_SQUARED = 1e-12  # m²: closer than this, a landmark cannot be linearised
# `correct`'s `out`: ẑ (2), ν (2), S's (s00, s01, s11), the NIS; OUT_SIZE entries in all
OUT_Z_HAT, OUT_NU, OUT_S, OUT_NIS, OUT_SIZE = 0, 2, 4, 7, 8
# where `propagate` and `record` write in an event row (`history.ROW_COLUMNS`): t, pose, cov
ROW_T, ROW_POSE, ROW_COV, ROW_SIZE = 0, 1, 4, 10
# where `record` writes in an observation row (`history.OBS_COLUMNS`)
OBS_T, OBS_EVENT, OBS_ID, OBS_Z, OBS_Z_HAT, OBS_NU, OBS_S, OBS_NIS = 0, 1, 2, 3, 5, 7, 9, 13
OBS_OUTCOME, OBS_LANDMARK, OBS_LANDMARK_COV, OBS_SIZE = 14, 15, 17, 21
_r, _o, _O = history.ROW_COLUMNS, history.OBS_COLUMNS, history.Outcome
if (
    (ACCEPTED, REJECTED, REFUSED, SINGULAR, MIN_RANGE_SQUARED)
    != (
        _O.ACCEPTED,
        _O.REJECTED,
        _O.REFUSED,
        _O.SINGULAR,
        models.MIN_RANGE_SQUARED,
    )
    or (ROW_T, ROW_POSE, ROW_COV, ROW_SIZE) != (_r.t, _r.pose.start, _r.cov.start, len(history.ROW))
    or (
        OBS_T,
        OBS_EVENT,
        OBS_ID,
        OBS_Z,
        OBS_Z_HAT,
        OBS_NU,
        OBS_S,
        OBS_NIS,
        OBS_OUTCOME,
        OBS_LANDMARK,
        OBS_LANDMARK_COV,
        OBS_SIZE,
    )
    != (
        _o.t,
        _o.event,
        _o.id,
        _o.z.start,
        _o.z_hat.start,
        _o.innovation.start,
        _o.S.start,
        _o.nis,
        _o.outcome,
        _o.landmark.start,
        _o.landmark_cov.start,
        len(history.OBS_ROW),
    )
):
    raise ImportError(
        "ekfslam.core.filter.kernels' constants disagree with ekfslam.core.filter.history or models"
    )
del _r, _o, _O


@njit(cache=True)
def wrap(a: float) -> float:
    """An angle in [-π, π)."""
    a = (a + math.pi) % (2.0 * math.pi) - math.pi
    return -math.pi if a >= math.pi else a


@njit(cache=True)
def cartesian_pose(row, c, x, y):
    """The 6 entries of an invariant pose covariance at row[c:c+6] made Cartesian, in place.

    T P Tᵀ with T = I + g e₃ᵀ, g = J p̂ = (-y, x): δp = ξ_p + J p̂ ξ_θ (`ekfslam.core.invariant`).
    """
    g0, g1 = -y, x
    s00, s01, s02, s11, s12, s22 = (
        row[c],
        row[c + 1],
        row[c + 2],
        row[c + 3],
        row[c + 4],
        row[c + 5],
    )
    row[c] = s00 + 2.0 * g0 * s02 + g0 * g0 * s22
    row[c + 1] = s01 + g0 * s12 + g1 * s02 + g0 * g1 * s22
    row[c + 2] = s02 + g0 * s22
    row[c + 3] = s11 + 2.0 * g1 * s12 + g1 * g1 * s22
    row[c + 4] = s12 + g1 * s22


@njit(cache=True)
def heading_direction(mu, d, dp, v):
    """v = (0, 0, 0, m̂_1y, -m̂_1x, ...) up to dp, 0 from dp to d: -J m̂, the map rows of ξ that a
    heading noise moves (`propagate`)."""
    v[0] = v[1] = v[2] = 0.0
    for i in range(3, dp, 2):
        v[i], v[i + 1] = mu[i + 1], -mu[i]
    for i in range(dp, d):
        v[i] = 0.0


@njit(cache=True)
def spread(mu, S, dp, rho, v):
    """Σ's map block += rho v vᵀ (lower triangle; v of `heading_direction`, filled here): the
    invariant filter's pending heading noise, one rank-1 pass."""
    heading_direction(mu, dp, dp, v)
    for i in range(3, dp):
        w = rho * v[i]
        row = S[i]
        for k in range(i + 1):  # from 0: v's pose entries are 0 (and the loop vectorises)
            row[k] += w * v[k]


@njit(cache=True)
def propagate(mu, S, d, us, dts, use_dts, N, fej, invariant, px, py, ts, rows, r0, record):
    """K predictions in a row, eqs. (6), (7) and (9); returns FEJ's (px, py) after them, and rho.

    us (K, 3) body-frame increments; dts (K,) their durations when use_dts (then N is the
    control covariance per second M, and step k gets R_k = V(θ_k) (M dt_k) V(θ_k)ᵀ), else N is
    a fixed state-space R. px, py: FEJ's first estimate of the position at this step, p̂(k|k-1).
    When record, the pose and its covariance after each step go to rows[r0 + k] (`ROW`).
    Returns (px, py, rho): rho = Σ_k r22, the heading noise the invariant filter still owes the
    map block (0 otherwise).

    Every motion Jacobian of eq. (7) is G = I + g e₃ᵀ with g = (g0, g1, 0) = (-Δy, Δx), so the
    product over the batch is I + (Σ g) e₃ᵀ: the pose-landmark cross-covariance Σ_rm <- G Σ_rm
    takes one O(n) pass for the whole batch, while the 3x3 pose block is stepped in floats.

    invariant: S holds the covariance of the right-invariant error ξ (`ekfslam.core.invariant`),
    whose propagation Jacobian is the identity (Barrau & Bonnabel 2015, the motion is
    group-affine): P += A R Aᵀ with A = `ekfslam.core.invariant.noise_map` at the state after
    the step, whose map rows v = -J m̂ (`heading_direction`) are the same for the whole batch.
    The pose block and the pose-map block (c vᵀ, c = Σ_k A_k R_k e₃'s pose rows) are added
    here, O(n); the map block's rho v vᵀ, O(n²), is returned as rho for the filter to add in
    its next correction's pass (`correct`) or `spread`. The rows get the Cartesian pose
    covariance T P Tᵀ, T = I + (-y, x, 0) e₃ᵀ.
    """
    x, y, th = mu[0], mu[1], mu[2]
    s00, s01, s02, s11, s12, s22 = S[0, 0], S[0, 1], S[0, 2], S[1, 1], S[1, 2], S[2, 2]
    n00, n01, n02, n11, n12, n22 = N[0, 0], N[0, 1], N[0, 2], N[1, 1], N[1, 2], N[2, 2]
    r00, r01, r02, r11, r12, r22 = n00, n01, n02, n11, n12, n22
    A = 0.0  # Σ g0 and Σ g1 over the batch
    B = 0.0
    c0 = c1 = c2 = 0.0  # invariant: Σ of A R e₃'s pose rows over the batch (its map rows: below)
    for k in range(us.shape[0]):
        c, s = math.cos(th), math.sin(th)
        dx = us[k, 0] * c - us[k, 1] * s  # eq. (6): the step in the world frame
        dy = us[k, 0] * s + us[k, 1] * c
        if fej:  # Δ between the predicted positions, not from the updated one
            g0, g1 = -(y + dy - py), x + dx - px
        else:
            g0, g1 = -dy, dx
        if use_dts:  # R = V (M dt) Vᵀ with V the rotation of eq. (5)
            dt = dts[k]
            cc, ss, cs = c * c, s * s, c * s
            r00 = (cc * n00 - 2.0 * cs * n01 + ss * n11) * dt
            r01 = (cs * (n00 - n11) + (cc - ss) * n01) * dt
            r11 = (ss * n00 + 2.0 * cs * n01 + cc * n11) * dt
            r02 = (c * n02 - s * n12) * dt
            r12 = (s * n02 + c * n12) * dt
            r22 = n22 * dt
        if invariant:  # F = I; the noise enters ξ through A = I + a e₃ᵀ, a = (y', -x')
            g0, g1 = 0.0, 0.0
            a0, a1 = y + dy, -(x + dx)
            r00, r01, r02, r11, r12 = (
                r00 + 2.0 * a0 * r02 + a0 * a0 * r22,
                r01 + a0 * r12 + a1 * r02 + a0 * a1 * r22,
                r02 + a0 * r22,
                r11 + 2.0 * a1 * r12 + a1 * a1 * r22,
                r12 + a1 * r22,
            )
            c0, c1, c2 = c0 + r02, c1 + r12, c2 + r22
        # eq. (9) on the pose block: G Σ Gᵀ + R, written out for G = I + g e₃ᵀ
        s00, s01, s02, s11, s12, s22 = (
            s00 + 2.0 * g0 * s02 + g0 * g0 * s22 + r00,
            s01 + g0 * s12 + g1 * s02 + g0 * g1 * s22 + r01,
            s02 + g0 * s22 + r02,
            s11 + 2.0 * g1 * s12 + g1 * g1 * s22 + r11,
            s12 + g1 * s22 + r12,
            s22 + r22,
        )
        x += dx
        y += dy
        th += us[k, 2]
        if not -math.pi <= th < math.pi:
            th = wrap(th)
        A += g0
        B += g1
        if record:
            row = rows[r0 + k]
            p, c = ROW_POSE, ROW_COV
            row[ROW_T], row[p], row[p + 1], row[p + 2] = ts[k], x, y, th
            row[c], row[c + 1], row[c + 2], row[c + 3], row[c + 4], row[c + 5] = (
                s00,
                s01,
                s02,
                s11,
                s12,
                s22,
            )
            if invariant:
                cartesian_pose(row, c, x, y)
        if invariant and not use_dts:  # the fixed R again for the next step (it was mapped)
            r00, r01, r02, r11, r12, r22 = n00, n01, n02, n11, n12, n22
        px, py = x, y
    mu[0], mu[1], mu[2] = x, y, th
    if invariant:  # the heading noise n_θ moves every landmark's ξ by -J m̂ n_θ
        for i in range(3, d, 2):  # the pose-map block += c vᵀ
            vx, vy = mu[i + 1], -mu[i]
            S[i, 0] += c0 * vx
            S[i, 1] += c1 * vx
            S[i, 2] += c2 * vx
            S[i + 1, 0] += c0 * vy
            S[i + 1, 1] += c1 * vy
            S[i + 1, 2] += c2 * vy
    else:
        for i in range(3, d):  # Σ_rm <- (Π G) Σ_rm: only x and y change (columns, lower half)
            S[i, 0] += A * S[i, 2]
            S[i, 1] += B * S[i, 2]
    S[0, 0], S[0, 1], S[0, 2], S[1, 1], S[1, 2], S[2, 2] = s00, s01, s02, s11, s12, s22
    S[1, 0], S[2, 0], S[2, 1] = s01, s02, s12
    return px, py, c2


@njit(cache=True)
def correct(mu, S, d, l, z0, z1, q00, q01, q11, jx, jy, invariant, rho, dp, gate, work, out):
    """One range-bearing observation of the landmark at l, eqs. (13)-(16); returns an outcome.

    jx, jy: the landmark relative to the robot where the Jacobian is evaluated (the current
    estimate, or FEJ's first estimates). gate: reject when the NIS exceeds it (inf: never).
    work: (2, capacity) scratch. out (OUT_SIZE,) receives ẑ (2) at OUT_Z_HAT, ν (2) at OUT_NU,
    S's (s00, s01, s11) at OUT_S and the NIS at OUT_NIS, NaN where not reached. Returns
    ACCEPTED (state updated), REJECTED (NIS above the gate), REFUSED (no linearisation: the
    landmark, or the observation, sits on the robot) or SINGULAR (S is not positive definite,
    or not finite: no gain); only ACCEPTED changes mu and S.

    invariant: S is the covariance of the right-invariant error ξ. The observation Jacobian in ξ
    is H = [-H_l | 0 | H_l] (the heading column vanishes: the bearing's -1 cancels H_l J (m - p)),
    and the correction K ν is applied through the exponential of SE_{1+n}(2), x̂ <- exp(Kν) x̂
    (Barrau & Bonnabel 2015, sec. IV), not added. rho, dp: the heading noise still owed to the
    map block up to dp (`propagate`): Σ is read as S + rho v vᵀ and an accepted correction adds
    it in its pass (then the filter owes nothing); work then needs a third row, for v.
    """
    out[:] = np.nan
    x, y, th = mu[0], mu[1], mu[2]
    dx, dy = mu[l] - x, mu[l + 1] - y
    q = dx * dx + dy * dy
    jq = jx * jx + jy * jy
    if not (q > MIN_RANGE_SQUARED and jq > MIN_RANGE_SQUARED):
        return REFUSED
    zh0, zh1 = math.sqrt(q), wrap(math.atan2(dy, dx) - th)
    nu0, nu1 = z0 - zh0, wrap(z1 - zh1)
    out[OUT_Z_HAT], out[OUT_Z_HAT + 1], out[OUT_NU], out[OUT_NU + 1] = zh0, zh1, nu0, nu1
    # eq. (14) on the rows (x, y, θ, mx, my) is H = [-H_l | -e₂ | H_l] with
    # H_l = [[a, b], [-e, f]]: the observation sees only the landmark relative to the robot,
    # so H Σ = H_l (Σ_l - Σ_xy) - e₂ Σ_θ comes from five rows of Σ: O(n), no lift.
    jr = math.sqrt(jq)
    a, b, e, f = jx / jr, jy / jr, jy / jq, jx / jq
    hth = 0.0 if invariant else 1.0  # minus the heading column of H
    h0, h1 = work[0], work[1]
    owed = rho != 0.0
    if owed:
        hv = work[2]
        heading_direction(mu, d, dp, hv)
        vl0, vl1 = rho * hv[l], rho * hv[l + 1]
    for k in range(d):  # Σ's rows 0, 1, 2, l, l+1, read from the lower triangle
        if k < 3:
            p0, p1, p2 = S[0, k], S[1, k], S[2, k]
        else:
            p0, p1, p2 = S[k, 0], S[k, 1], S[k, 2]
        m0 = S[l, k] if k <= l else S[k, l]
        m1 = S[l + 1, k] if k <= l + 1 else S[k, l + 1]
        if owed:
            m0 += vl0 * hv[k]
            m1 += vl1 * hv[k]
        u, v = m0 - p0, m1 - p1
        h0[k] = a * u + b * v
        h1[k] = -e * u + f * v - hth * p2
    # S = H Σ Hᵀ + Q (eq. 15's innovation covariance), from H Σ's columns the same way
    s00 = a * (h0[l] - h0[0]) + b * (h0[l + 1] - h0[1]) + q00
    s01 = -e * (h0[l] - h0[0]) + f * (h0[l + 1] - h0[1]) - hth * h0[2] + q01
    s11 = -e * (h1[l] - h1[0]) + f * (h1[l + 1] - h1[1]) - hth * h1[2] + q11
    out[OUT_S], out[OUT_S + 1], out[OUT_S + 2] = s00, s01, s11
    # S = L Lᵀ (Cholesky, 2x2); w = L⁻¹ ν makes the NIS νᵀ S⁻¹ ν = |w|²
    det = s00 * s11 - s01 * s01
    if not (0.0 < s00 < math.inf and 0.0 < det < math.inf):  # also false for NaN
        return SINGULAR
    l00 = math.sqrt(s00)
    l10 = s01 / l00
    l11 = math.sqrt(det) / l00  # = √(s11 - l10²)
    w0 = nu0 / l00
    w1 = (nu1 - l10 * w0) / l11
    nis = w0 * w0 + w1 * w1
    out[OUT_NIS] = nis
    if nis > gate:
        return REJECTED
    # eqs. (15)-(16) with W = L⁻¹ H Σ: K = Σ Hᵀ S⁻¹ = Wᵀ L⁻¹, so K S Kᵀ = Wᵀ W and Σ -= Wᵀ W,
    # which for the optimal gain equals Joseph's form (I-KH)Σ(I-KH)ᵀ + KQKᵀ, and keeps Σ
    # symmetric; the mean moves by K ν = (H Σ)ᵀ S⁻¹ ν = (H Σ)ᵀ L⁻ᵀ w.
    f00, f10, f11 = 1.0 / l00, -l10 / (l00 * l11), 1.0 / l11
    k1 = w1 / l11
    k0 = (w0 - l10 * k1) / l00
    if invariant:
        retract(mu, d, h0, h1, k0, k1)
    W0, W1 = h0, h1  # in place: column k of H Σ is read before it is overwritten
    for k in range(d):
        p0, p1 = h0[k], h1[k]
        if not invariant:
            mu[k] += k0 * p0 + k1 * p1
        W0[k] = f00 * p0
        W1[k] = f10 * p0 + f11 * p1
    if not -math.pi <= mu[2] < math.pi:
        mu[2] = wrap(mu[2])
    if owed:  # Σ += rho v vᵀ - Wᵀ W in the same pass
        for i in range(d):
            a0, a1, w = W0[i], W1[i], rho * hv[i]
            row = S[i]
            for k in range(i + 1):
                row[k] += w * hv[k] - (a0 * W0[k] + a1 * W1[k])
    else:
        for i in range(d):  # Σ -= Wᵀ W: the only O(n²) step, one pass over the lower triangle
            a0, a1 = W0[i], W1[i]
            row = S[i]
            for k in range(i + 1):
                row[k] -= a0 * W0[k] + a1 * W1[k]
    S[0, 1], S[0, 2], S[1, 2] = S[1, 0], S[2, 0], S[2, 1]  # the pose block stays whole
    return ACCEPTED


@njit(cache=True)
def retract(mu, d, h0, h1, k0, k1):
    """mu <- exp(ξ) mu on SE_{1+n}(2), ξ = K ν = (H Σ)ᵀ (k0, k1) (`ekfslam.core.invariant.retract`).

    θ += ξ_θ and every point v (the position, each landmark) becomes R(ξ_θ) v + V(ξ_θ) ξ_v with
    V(φ) = (sin φ / φ) I + ((1 - cos φ) / φ) J, the left Jacobian of SO(2).
    """
    w = k0 * h0[2] + k1 * h1[2]
    c, s = math.cos(w), math.sin(w)
    if abs(w) < 1e-6:  # the series of sin w / w and (1 - cos w) / w
        va, vb = 1.0 - w * w / 6.0, 0.5 * w
    else:
        va, vb = s / w, (1.0 - c) / w
    for t in range((d - 1) // 2):  # the points start at 0 (the position), 3, 5, ...
        i = 0 if t == 0 else 1 + 2 * t
        j = i + 1
        x0, x1 = mu[i], mu[j]
        e0, e1 = k0 * h0[i] + k1 * h1[i], k0 * h0[j] + k1 * h1[j]
        mu[i] = c * x0 - s * x1 + va * e0 - vb * e1
        mu[j] = s * x0 + c * x1 + vb * e0 + va * e1
    th = mu[2] + w
    mu[2] = th if -math.pi <= th < math.pi else wrap(th)


@njit(cache=True)
def record(mu, S, l, t, landmark_id, z0, z1, out, code, invariant, rho, dp, rows, n, obs, m):
    """Write the state after an observation to rows[n] (`ROW`) and the observation to obs[m].

    l < 0: no landmark slot (a refused first sighting); its estimate is then NaN. out: what
    `correct` wrote (ẑ, ν, S, NIS), NaN where there was none. code: the `history.Outcome`, as an
    int. invariant: S is in invariant coordinates, with rho v vᵀ still owed to its map block up
    to dp (`propagate`); the rows get the Cartesian covariances.
    """
    row = rows[n]
    p, c = ROW_POSE, ROW_COV
    row[ROW_T], row[p], row[p + 1], row[p + 2] = t, mu[0], mu[1], mu[2]
    row[c], row[c + 1], row[c + 2], row[c + 3], row[c + 4], row[c + 5] = (
        S[0, 0],
        S[0, 1],
        S[0, 2],
        S[1, 1],
        S[1, 2],
        S[2, 2],
    )
    if invariant:
        cartesian_pose(row, c, mu[0], mu[1])
    o = obs[m]
    o[OBS_T], o[OBS_EVENT], o[OBS_ID], o[OBS_Z], o[OBS_Z + 1] = t, n, landmark_id, z0, z1
    o[OBS_Z_HAT], o[OBS_Z_HAT + 1] = out[OUT_Z_HAT], out[OUT_Z_HAT + 1]
    o[OBS_NU], o[OBS_NU + 1] = out[OUT_NU], out[OUT_NU + 1]
    s00, s01, s11 = out[OUT_S], out[OUT_S + 1], out[OUT_S + 2]
    o[OBS_S], o[OBS_S + 1], o[OBS_S + 2], o[OBS_S + 3] = s00, s01, s01, s11
    o[OBS_NIS] = out[OUT_NIS]
    o[OBS_OUTCOME] = code
    if l < 0:
        o[OBS_LANDMARK:OBS_SIZE] = np.nan
    else:
        o[OBS_LANDMARK], o[OBS_LANDMARK + 1] = mu[l], mu[l + 1]
        c = OBS_LANDMARK_COV
        a, b, e = S[l, l], S[l + 1, l], S[l + 1, l + 1]
        if invariant:  # δm = ξ_m + J m̂ ξ_θ
            g0, g1, p0, p1, p22 = -mu[l + 1], mu[l], S[l, 2], S[l + 1, 2], S[2, 2]
            if l < dp:  # the owed heading noise, v = -(g0, g1)
                a, b, e = a + rho * g0 * g0, b + rho * g0 * g1, e + rho * g1 * g1
            a, b, e = (
                a + 2.0 * g0 * p0 + g0 * g0 * p22,
                b + g0 * p1 + g1 * p0 + g0 * g1 * p22,
                e + 2.0 * g1 * p1 + g1 * g1 * p22,
            )
        o[c], o[c + 1], o[c + 2], o[c + 3] = a, b, b, e


@njit(cache=True)
def mirror(S, d):
    """Copy Σ's lower triangle onto its upper one (the used d x d block), in 32 x 32 tiles."""
    for ib in range(0, d, 32):
        for kb in range(0, ib + 1, 32):  # the tiles on and below the diagonal
            for i in range(ib, min(ib + 32, d)):
                for k in range(kb, min(kb + 32, i)):
                    S[k, i] = S[i, k]
