"""The iterated update (Gauss-Newton IEKF), compiled: where to linearise eqs. (13)-(14).

`FilterConfig(iterations=N)` with N > 1 re-linearises the range-bearing observation at the
updated estimate before it commits the update (Bell & Cathey, "The iterated Kalman filter update
as a Gauss-Newton method", IEEE T-AC 1993). In the filter's error coordinates δ (the Cartesian
error for the standard EKF, the right-invariant ξ for the invariant one), with x(δ) = x̂ + δ or
exp(δ) x̂, each iteration i linearises h at x_i = x(δ_i):

    r_i = z - h(x_i) + H_i δ_i,   K_i = Σ H_iᵀ (H_i Σ H_iᵀ + Q)⁻¹,   δ_{i+1} = K_i r_i,

with H_i eq. (14)'s Jacobian at x_i (for ξ, to first order in the composition: exp(δ) x̂ is
taken as exp(δ - δ_i) x_i). The last one is the ordinary update of eqs. (15)-(16) with H_N
and r_N in place of H and ν: μ <- x(K_N r_N), Σ <- Σ - K_N S_N K_Nᵀ. Iteration 1 is the plain
EKF.

Plain Gauss-Newton can climb: with the heading uncertain and a landmark just placed by eq. (12),
its steps in the Cartesian coordinates overshoot and oscillate (the tests have such a case). So
a linearisation after the first is taken only when its step lowers the MAP cost of the
observation, ½|z - h(x)|²_Q⁻¹ + ½ δᵀ Σ⁻¹ δ (the prior term is ½ wᵀ (S - Q) w for δ = Σ Hᵀ w,
no inverse of Σ needed); otherwise the last step that did is committed (at worst the plain
EKF's). The iterations stop once a step moves no entry of δ by `TOLERANCE` or more: below it a
cost difference is lost in rounding.

Only five entries of δ move h and H (the pose and the landmark seen), so the iterations run on
the 5x5 block of Σ they need, O(1) each; this module returns the linearisation to take as an
equivalent observation z' = h(x̂) + r_N and the relative position at which to evaluate H, and
`ekfslam.core.filter.kernels.correct` then commits it in its usual O(n²) pass. The gate, and the
innovation, S and NIS recorded in the history, are the first linearisation's: the iterations
change where the filter ends, not which sightings it takes or the χ² test of them.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ekfslam.core.filter import kernels

# numba's cache is keyed on this file alone: the constants are written here and checked.
MIN_RANGE_SQUARED = 1e-12
OUT_Z_HAT, OUT_NU, OUT_S, OUT_NIS = 0, 2, 4, 7
#: where `linearise` writes in its result: z' (2), the relative position (2), iterations run
RES_Z, RES_J, RES_ITERATIONS, RES_SIZE = 0, 2, 4, 5
#: the iterations stop early when a step moves no entry of δ by this much (m, rad): 0.1 µm is
#: far below any noise, and smaller steps change the cost by less than it can resolve
TOLERANCE = 1e-7
USE, PLAIN = 0, 1  # `linearise`'s verdicts
if (MIN_RANGE_SQUARED, OUT_Z_HAT, OUT_NU, OUT_S, OUT_NIS) != (
    kernels.MIN_RANGE_SQUARED,
    kernels.OUT_Z_HAT,
    kernels.OUT_NU,
    kernels.OUT_S,
    kernels.OUT_NIS,
):
    raise ImportError("ekfslam.core.filter.iterated's constants disagree with kernels")


@njit(cache=True)
def _wrap(a):
    a = (a + math.pi) % (2.0 * math.pi) - math.pi
    return -math.pi if a >= math.pi else a


@njit(cache=True)
def linearise(mu, S, l, z0, z1, q00, q01, q11, invariant, rho, dp, iterations, gate, first, res):
    """Iterate the linearisation point of one observation of the landmark at l (see the module).

    mu, S, l, z, q, invariant, rho, dp: as `kernels.correct`. gate: the NIS test of the first
    linearisation. first (OUT_SIZE,): receives the first linearisation's ẑ, ν, S and NIS, laid
    out as `kernels.correct`'s `out`. res (RES_SIZE,): z' and the relative position (jx, jy) to
    hand `kernels.correct`, and the linearisations run up to the one taken.

    Returns USE (res holds the linearisation to take: call `correct` with z', (jx, jy), no gate),
    or PLAIN (the first linearisation is refused, singular or gated: call `correct` as without
    iterations, which finds the same verdict).
    """
    idx = (0, 1, 2, l, l + 1)
    P = np.empty((5, 5))
    for i in range(5):
        for k in range(5):
            a, b = idx[i], idx[k]
            P[i, k] = S[a, b] if b <= a else S[b, a]
    if invariant and rho != 0.0 and l < dp:  # the heading noise still owed, v = -J m̂ (rows l)
        v3, v4 = mu[l + 1], -mu[l]
        P[3, 3] += rho * v3 * v3
        P[3, 4] += rho * v3 * v4
        P[4, 3] += rho * v3 * v4
        P[4, 4] += rho * v4 * v4
    x0, y0, th0, mx0, my0 = mu[0], mu[1], mu[2], mu[l], mu[l + 1]
    hth = 0.0 if invariant else 1.0
    d = np.zeros(5)  # δ on (x, y, θ, mx, my)
    h = np.zeros((2, 5))
    HP = np.zeros((2, 5))
    zh00 = zh01 = prior = best = c0 = c1 = cx = cy = 0.0
    qdet = q00 * q11 - q01 * q01
    ran = 0
    for it in range(iterations + 1):  # the last pass only scores where the last step landed
        if invariant:  # x(δ) = exp(δ) x̂ (`kernels.retract`)
            w = d[2]
            c, s = math.cos(w), math.sin(w)
            if abs(w) < 1e-6:
                va, vb = 1.0 - w * w / 6.0, 0.5 * w
            else:
                va, vb = s / w, (1.0 - c) / w
            px = c * x0 - s * y0 + va * d[0] - vb * d[1]
            py = s * x0 + c * y0 + vb * d[0] + va * d[1]
            mx = c * mx0 - s * my0 + va * d[3] - vb * d[4]
            my = s * mx0 + c * my0 + vb * d[3] + va * d[4]
            th = th0 + w
        else:
            px, py, th, mx, my = x0 + d[0], y0 + d[1], th0 + d[2], mx0 + d[3], my0 + d[4]
        rx, ry = mx - px, my - py
        q = rx * rx + ry * ry
        if not q > MIN_RANGE_SQUARED:
            break  # keep the last linearisation that could be made
        jr = math.sqrt(q)
        a, b, e, f = rx / jr, ry / jr, ry / q, rx / q
        # eq. (14) on (x, y, θ, mx, my); the invariant one has no heading column
        h[0, 0], h[0, 1], h[0, 2], h[0, 3], h[0, 4] = -a, -b, 0.0, a, b
        h[1, 0], h[1, 1], h[1, 2], h[1, 3], h[1, 4] = e, -f, -hth, -e, f
        zh0, zh1 = jr, _wrap(math.atan2(ry, rx) - th)
        hd0 = hd1 = s00 = s01 = s11 = 0.0
        for k in range(5):  # H δ, H Σ and S = H Σ Hᵀ + Q, written out (no BLAS in the kernel)
            hd0 += h[0, k] * d[k]
            hd1 += h[1, k] * d[k]
            t0 = t1 = 0.0
            for i in range(5):
                t0 += h[0, i] * P[i, k]
                t1 += h[1, i] * P[i, k]
            HP[0, k], HP[1, k] = t0, t1
            s00 += t0 * h[0, k]
            s01 += t0 * h[1, k]
            s11 += t1 * h[1, k]
        s00, s01, s11 = s00 + q00, s01 + q01, s11 + q11
        r0 = z0 - zh0 + hd0
        r1 = _wrap(z1 - zh1) + hd1
        det = s00 * s11 - s01 * s01
        if not (0.0 < s00 < math.inf and 0.0 < det < math.inf):
            break
        if it == 0:
            nis = (s11 * r0 * r0 - 2.0 * s01 * r0 * r1 + s00 * r1 * r1) / det
            first[OUT_Z_HAT], first[OUT_Z_HAT + 1] = zh0, zh1
            first[OUT_NU], first[OUT_NU + 1] = r0, r1
            first[OUT_S], first[OUT_S + 1], first[OUT_S + 2] = s00, s01, s11
            first[OUT_NIS] = nis
            if nis > gate or not qdet > 0.0:
                return PLAIN
            zh00, zh01 = zh0, zh1
            res[RES_Z], res[RES_Z + 1], res[RES_J], res[RES_J + 1] = zh0 + r0, zh1 + r1, rx, ry
            ran = 1  # the plain EKF's step, always taken
        else:  # the MAP cost at δ_it, where the last step landed
            t0, t1 = z0 - zh0, _wrap(z1 - zh1)
            cost = 0.5 * (q11 * t0 * t0 - 2.0 * q01 * t0 * t1 + q00 * t1 * t1) / qdet + prior
            if it >= 2:  # did linearisation it - 1's step lower it? Then it is the one to take
                if not cost < best:
                    break
                res[RES_Z], res[RES_Z + 1], res[RES_J], res[RES_J + 1] = c0, c1, cx, cy
                ran = it
            best = cost
            if it == iterations:
                break
            c0, c1, cx, cy = zh00 + r0, zh01 + r1, rx, ry  # linearisation it, on probation
        w0 = (s11 * r0 - s01 * r1) / det  # S⁻¹ r
        w1 = (s00 * r1 - s01 * r0) / det
        # ½ δᵀ Σ⁻¹ δ at the next point, δ = Σ Hᵀ w: ½ wᵀ (S - Q) w, no inverse of Σ needed
        prior = 0.5 * ((s00 - q00) * w0 * w0 + 2.0 * (s01 - q01) * w0 * w1 + (s11 - q11) * w1 * w1)
        moved = 0.0
        for k in range(5):  # δ <- K r = (H Σ)ᵀ S⁻¹ r
            new = HP[0, k] * w0 + HP[1, k] * w1
            moved = max(moved, abs(new - d[k]))
            d[k] = new
        if it > 0 and moved < TOLERANCE:  # converged: this step lands where it started
            res[RES_Z], res[RES_Z + 1], res[RES_J], res[RES_J + 1] = c0, c1, cx, cy
            ran = it + 1
            break
    res[RES_ITERATIONS] = ran
    return USE if ran > 0 else PLAIN
