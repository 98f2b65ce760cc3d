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

Only five entries of δ move h and H (the pose and the landmark seen), so the iterations run on the
5x5 block of Σ they need, O(1) each; this module returns the linearisation to take as an equivalent
observation z' = h(x̂) + r_N and the point at which to evaluate H, and
`ekfslam.core.filter.steps.correct` then commits it in its usual O(n²) pass. Like the steps, it runs
as written or compiled (`ekfslam.core.filter.backend`), with the filter's sensor model. The gate,
and the innovation, S and NIS recorded in the history, are the first linearisation's: the iterations
change where the filter ends, not which sightings it takes or the χ² test of them."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.filter.history import OBS_NIS
from ekfslam.core.filter.predictions import indices
from ekfslam.core.filter.steps import (
    Linearization,
    Storage,
    Update,
    apart,
    cholesky,
    jacobians,
    owed_direction,
    positive,
    record_innovation,
    sensor,
    solve_lower,
    solve_upper,
)
from ekfslam.core.filter.symmetric import block
from ekfslam.core.invariant import retract

Array = NDArray[np.float64]

#: the iterations stop early when a step moves no entry of δ by this much (m, rad): 0.1 µm is
#: far below any noise, and smaller steps change the cost by less than it can resolve
TOLERANCE = 1e-7


def linearise(
    storage: Storage, d: int, l: int, update: Update, iterations: int, obs: Array
) -> Array:
    """Iterate the linearisation point of one observation of the landmark at l (see the module).

    obs (`obs_row`) receives the first linearisation's ẑ, ν, S and NIS, as `correct` writes them.
    Returns (6 + m,): the point (5,) at which to evaluate H and the equivalent observation z'
    (m,), for `correct` with no gate, and how many linearisations were run up to the one taken;
    or NaN
    when the first linearisation is refused, singular or gated (`correct` as without iterations
    then finds the same verdict).
    """
    mu, Sigma, _, owed, lin = storage
    z, Q, gate, _ = update
    invariant = lin == Linearization.INVARIANT
    P = block(Sigma, indices(l), indices(l))  # Σ on (pose, landmark)
    if owed[0] != 0.0:  # the heading noise the invariant filter still owes
        v = owed_direction(storage, d)[l : l + 2]
        P[3:, 3:] += owed[0] * np.outer(v, v)
    x_hat = np.concatenate((mu[:3], mu[l : l + 2]))
    C_Q = cholesky(Q)
    m = z.shape[0]
    result = np.full(6 + m, np.nan)
    delta = np.zeros(5)  # δ on (x, y, θ, mx, my)
    z_hat_0 = np.zeros(m)  # h(x̂)
    on_probation = np.full(6 + m, np.nan)  # linearisation it - 1: taken if its step lowers the cost
    prior = best = 0.0
    for it in range(iterations + 1):  # the last pass only scores where the last step landed
        x = retract(x_hat, delta) if invariant else x_hat + delta  # x(δ)
        if not apart(x[:3], x[3:]):
            break  # keep the last linearisation that could be made
        H_r, H_l = jacobians(storage, x)
        H = np.hstack((H_r, H_l))  # eq. (14) on (x, y, θ, mx, my)
        z_hat = sensor.h(x[:3], x[3:])
        HP = H @ P
        S = HP @ H.T + Q
        r = sensor.innovation(z, z_hat) + H @ delta  # r_i = z - h(x_i) + H_i δ_i
        C = cholesky(S)
        if not positive(C):
            break
        if it == 0:
            w = solve_lower(C, r)
            nis = w @ w
            record_innovation(obs, z_hat, r, S)
            obs[OBS_NIS] = nis
            if nis > gate or not positive(C_Q):
                return result
            z_hat_0 = z_hat
            result[:5], result[5 : 5 + m], result[5 + m] = (
                x,
                z_hat_0 + r,
                1,
            )  # the plain EKF's, always taken
        else:  # the MAP cost at δ_it, where the last step landed
            t = solve_lower(C_Q, sensor.innovation(z, z_hat))
            cost = 0.5 * t @ t + prior  # ½ tᵀ Q⁻¹ t + the prior's
            if it >= 2:  # did linearisation it - 1's step lower it? Then it is the one to take
                if not cost < best:
                    break
                result[: 5 + m], result[5 + m] = on_probation[: 5 + m], it
            best = cost
            if it == iterations:
                break
            on_probation[:5], on_probation[5 : 5 + m] = x, z_hat_0 + r
        w = solve_upper(C, solve_lower(C, r))  # S⁻¹ r = C⁻ᵀ C⁻¹ r
        # ½ δᵀ Σ⁻¹ δ at the next point, δ = Σ Hᵀ w: ½ wᵀ (S - Q) w, no inverse of Σ needed
        prior = 0.5 * w @ (S - Q) @ w
        step = HP.T @ w  # δ <- K r = (H Σ)ᵀ S⁻¹ r
        moved = np.max(np.abs(step - delta))
        delta = step
        if it > 0 and moved < TOLERANCE:  # converged: this step lands where it started
            result[: 5 + m], result[5 + m] = on_probation[: 5 + m], it + 1
            break
    return result
