"""The eq. (17) solver: the minimiser of the mean distance, found to convergence.

`ekfslam.analysis.alignment` is the interface; this is the numerical machinery behind
`align_mean_distance`, working on centred maps scaled to unit size. IRLS (iteratively
reweighted Kabsch) gives a warm start; Newton's method finishes, either pinned on a kink (one
landmark fitted exactly, only θ free) or smooth on all three parameters, and each finish is
certified before it is accepted.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ekfslam.geometry import rotation, weighted_kabsch

Array = NDArray[np.float64]

# IRLS is only a warm start: it converges linearly (for 8 landmarks, a median of ~80 steps and
# sometimes tens of thousands to reach 1e-12), so Newton finishes.
_WARM_START_REL_CHANGE = 1e-4
_WARM_START_MAX_STEPS = 50
_MAX_HALVINGS = 30  # of a Newton step, before falling back to an IRLS step
# IRLS steps in a row, closing in on an exact fit, that end the smooth finish (IRLS creeps onto
# an exact fit, which the kink finish then solves directly); a round is one of each finish.
_MAX_FALLBACKS = 5
_MAX_FINISHES = 4
# A Newton step predicted to lower Σ d_i by less than this fraction cannot be checked by
# evaluating the objective (rounding is ~N × 1e-16): it is taken whole, as the last step.
_UNRESOLVABLE = 1e-13
# Optimality check: the Newton step left at the answer (translation over map size, and rad) must
# be this small. A step, unlike a gradient, stays meaningful when the Hessian is huge, as it is
# beside an exactly fitted landmark.
_STEP_TOL = 1e-9


def minimise(X: Array, Y: Array, tol: float, budget: int) -> tuple[Array, int, bool]:
    """Minimise Σ_i d_i (N times eq. 17); returns (x, y, θ), the steps used and convergence."""
    params = weighted_kabsch(X, Y, np.ones(len(X)))
    d = distances(params, X, Y)
    if len(X) == 2 or d.max() <= tol:  # an exact fit, or the N = 2 family of minimisers
        return params, 0, True
    f, used = float(d.sum()), 0
    while used < min(_WARM_START_MAX_STEPS, budget):
        params = weighted_kabsch(X, Y, 1.0 / np.maximum(d, tol))
        d = distances(params, X, Y)
        used += 1
        f, f_old = float(d.sum()), f
        if f_old - f <= _WARM_START_REL_CHANGE * f:
            break
    tried = []
    for _ in range(_MAX_FINISHES):
        k = int(np.argmin(d))
        pinned, steps = _pinned_newton(X, Y, k, params[2], tol, budget - used)
        used += steps
        tried.append(pinned)
        certified, pull = _kink_check(pinned, X, Y, k)
        if certified:
            return pinned, used, True
        # Not a minimum: step off the kink downhill first, or the IRLS fallback in the smooth
        # finish (weight 1/d_k, huge) would pull us straight back onto it.
        if float(distances(pinned, X, Y).sum()) <= float(d.sum()) and pull.any():
            params = _escape(pinned, pull, X, Y)
        params, steps = _smooth_newton(X, Y, params, tol, budget - used)
        used += steps
        tried.append(params)
        if _smooth_certified(params, X, Y):
            return params, used, True
        d = distances(params, X, Y)  # Newton gave way to IRLS near another exact fit: try it
    return min(tried, key=lambda p: float(distances(p, X, Y).sum())), used, False


def distances(params: Array, X: Array, Y: Array) -> Array:
    r = X @ rotation(params[2]).T + params[:2] - Y
    return np.hypot(r[:, 0], r[:, 1])


def _derivatives(params: Array, X: Array, Y: Array) -> tuple[Array, Array]:
    """Gradient (3,) and Hessian (3, 3) of Σ_i d_i; needs every d_i > 0.

    With q_i = R X_i, r_i = q_i + t − Y_i, n_i = r_i/d_i and m_i = n_i turned by 90°, the
    Jacobian of r_i is [I | q_i⊥], so the gradient is Σ [n_i, n_i·q_i⊥] and the Hessian is
    Σ g_i g_iᵀ/d_i with g_i = [m_i, m_i·q_i⊥], plus −Σ n_i·q_i in the θθ entry (R'' = −R).
    """
    q = X @ rotation(params[2]).T
    r = q + params[:2] - Y
    d = np.hypot(r[:, 0], r[:, 1])
    nx, ny = r[:, 0] / d, r[:, 1] / d
    n_dot_q = nx * q[:, 0] + ny * q[:, 1]  # equals m_i·q_i⊥
    grad = np.array([nx.sum(), ny.sum(), np.sum(ny * q[:, 0] - nx * q[:, 1])])
    g = np.stack([-ny, nx, n_dot_q])  # (3, N): the g_i as columns
    hess = (g / d) @ g.T
    hess[2, 2] -= n_dot_q.sum()
    return grad, hess


def _smooth_newton(X: Array, Y: Array, params: Array, tol: float, budget: int) -> tuple[Array, int]:
    """Damped Newton on Σ_i d_i, with an IRLS step wherever Newton cannot descend."""
    f, used, fallbacks = float(distances(params, X, Y).sum()), 0, 0
    while used < budget and fallbacks < _MAX_FALLBACKS:
        used += 1
        d = distances(params, X, Y)
        new = None
        if d.min() > tol:
            grad, hess = _derivatives(params, X, Y)
            lowest = np.linalg.eigvalsh(hess)[0]
            if lowest <= 0:  # θ can make Σ d_i locally concave: shift to a descent direction
                hess = hess + (1e-3 * np.abs(hess).max() - lowest) * np.eye(3)
            step = -np.linalg.solve(hess, grad)
            if lowest > 0 and -0.5 * grad @ step <= _UNRESOLVABLE * f:
                return params + step, used
            alpha = 1.0
            for _ in range(_MAX_HALVINGS):
                if float(distances(params + alpha * step, X, Y).sum()) < f:
                    new = params + alpha * step
                    break
                alpha *= 0.5
        # count IRLS steps in a row only while they close in on an exact fit
        fallbacks = fallbacks + 1 if new is None and d.min() < 1e-3 * np.median(d) else 0
        if new is None:
            new = weighted_kabsch(X, Y, 1.0 / np.maximum(d, tol))
        f_new = float(distances(new, X, Y).sum())
        if f_new > f:  # the IRLS fallback failed too: we are at the floating-point floor
            break
        new, params, f = params, new, f_new
        if np.abs(params - new).max() <= tol:
            break
    return params, used


def _pinned(X: Array, Y: Array, k: int) -> Array:
    """Landmarks fitted whenever k is: k and any exact duplicate of it (True in the mask)."""
    return np.all(X == X[k], axis=1) & np.all(Y == Y[k], axis=1)


def _pinned_newton(
    X: Array, Y: Array, k: int, theta: float, tol: float, budget: int
) -> tuple[Array, int]:
    """Minimise eq. (17) with landmark k fitted exactly: t = Y_k − R(θ) X_k, only θ is free.

    h(θ) = Σ_{i≠k} ‖R(θ)(X_i − X_k) − (Y_i − Y_k)‖ is solved by Newton's method with halving;
    returns the full parameters (x, y, θ) and the steps used.
    """
    free = ~_pinned(X, Y, k)
    A, B = X[free] - X[k], Y[free] - Y[k]

    def h(th: float) -> float:
        r = A @ rotation(th).T - B
        return float(np.hypot(r[:, 0], r[:, 1]).sum())

    value, used = h(theta), 0
    while used < budget:
        used += 1
        q = A @ rotation(theta).T
        r = q - B
        d = np.hypot(r[:, 0], r[:, 1])
        if d.min() == 0.0:  # a second exact fit: a kink in θ too, leave it to the checks
            break
        n = r / d[:, None]
        slope = float(np.sum(n[:, 1] * q[:, 0] - n[:, 0] * q[:, 1]))  # Σ n_i·q_i⊥
        n_dot_q = np.sum(n * q, axis=1)  # equals m_i·q_i⊥, m_i = n_i turned by 90°
        curvature = float(np.sum(n_dot_q**2 / d) - n_dot_q.sum())
        # where h is concave, go downhill by up to half a radian (the halving finds the length)
        step = -slope / curvature if curvature > 0 else -math.copysign(0.5, slope)
        if curvature > 0 and 0.5 * slope**2 / curvature <= _UNRESOLVABLE * value:
            theta += step
            break
        for _ in range(_MAX_HALVINGS):
            trial = h(theta + step)
            if trial <= value:
                break
            step *= 0.5
        else:
            break
        theta, value = theta + step, trial
        if abs(step) <= tol:
            break
    t = Y[k] - rotation(theta) @ X[k]
    return np.array([t[0], t[1], theta]), used


def _kink_check(params: Array, X: Array, Y: Array, k: int) -> tuple[bool, Array]:
    """Is `params` (landmark k fitted exactly) a minimum of eq. (17)? Also returns the pull.

    The other landmarks' gradient g (3,) must be cancelled by subgradients [u, u·q_k⊥] of the
    c pinned landmarks' ‖r_k‖ (c = 1 unless k has exact duplicates), ‖u‖ ≤ c: so the pull g_xy
    on the translation must have norm ≤ c, and the slope along the family of transforms that
    keep k fitted must vanish (Newton step ≤ _STEP_TOL rad), with positive curvature.
    """
    pinned = _pinned(X, Y, k)
    if distances(params, X[~pinned], Y[~pinned]).min() == 0.0:  # a second, distinct exact fit
        return False, np.zeros(2)
    grad, hess = _derivatives(params, X[~pinned], Y[~pinned])
    q_k = rotation(params[2]) @ X[k]
    along = np.array([q_k[1], -q_k[0], 1.0])  # d(params)/dθ with t = Y_k − R(θ) X_k
    slope, curvature = float(grad @ along), float(along @ hess @ along)
    pull = grad[:2]
    ok = np.hypot(*pull) <= pinned.sum() and curvature > 0 and abs(slope) <= _STEP_TOL * curvature
    return bool(ok), pull


def _escape(pinned: Array, pull: Array, X: Array, Y: Array) -> Array:
    """Step off a kink that is not a minimum, along −pull, where eq. (17) falls at ≥ ‖pull‖ − 1.

    The step length is the best of a geometric ladder: the smooth minimum can lie anywhere from
    the map's size down to rounding error away from the kink.
    """
    direction = -pull / np.hypot(*pull)
    steps = np.logspace(0.0, -12.0, 49)
    r = X @ rotation(pinned[2]).T + pinned[:2] - Y  # a pure shift: the residuals just move
    shifted = r[None, :, :] + steps[:, None, None] * direction
    best = steps[int(np.argmin(np.hypot(shifted[..., 0], shifted[..., 1]).sum(axis=1)))]
    return pinned + best * np.array([direction[0], direction[1], 0.0])


def _smooth_certified(params: Array, X: Array, Y: Array) -> bool:
    """Is `params` a smooth minimum of eq. (17): no Newton step left, positive-definite Hessian?"""
    if distances(params, X, Y).min() == 0.0:
        return False
    grad, hess = _derivatives(params, X, Y)
    if not np.isfinite(hess).all() or np.linalg.eigvalsh(hess).min() <= 0:
        return False
    return bool(np.abs(np.linalg.solve(hess, grad)).max() <= _STEP_TOL)
