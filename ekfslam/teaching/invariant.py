"""The invariant EKF's Jacobians derived with sympy: the right-invariant error on SE_{1+n}(2).

Barrau & Bonnabel, "An EKF-SLAM algorithm with consistency properties" (2015) keep, instead of
the Cartesian error of eqs. (7) and (14), the error ξ of X = exp(ξ) X̂ on the group of a pose and
its landmarks (`ekfslam.core.invariant`). Here each map is written with the group's exact
exponential and logarithm and differentiated at ξ = 0, for one landmark (the others behave the
same, block by block):

- propagation, eq. (6) moved into ξ: ξ' = log(f(exp(ξ) X̂, u) f(X̂, u)⁻¹); its Jacobian is the
  identity (the motion is group-affine: a robot that moves does not change the error's
  coordinates), where eq. (7)'s G depends on the estimate;
- the pose noise, Cartesian n (R = V M Vᵀ) after the step: ∂ξ'/∂n, which turns every landmark's
  ξ by -J m̂ n_θ (so the noise, unlike G, reaches the map's rows);
- observation, eq. (13): ẑ(exp(ξ) X̂); its Jacobian has a zero heading column, and its position
  and landmark blocks are eq. (14)'s: the bearing's -1 cancels against H_l J (m - p);
- a new landmark, eq. (12): ξ_m of m(exp(ξ) X̂, z + δz), which is ξ_p + G_z δz.

Derivations are cached (sympy is slow); nothing is derived at import time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np
import sympy as sp

from ekfslam.teaching.derivations import (
    CONTROL,
    LANDMARK,
    MEASUREMENT,
    POSE,
    inverse_observation_model,
    motion_model,
    observation_model,
)

#: The invariant error of a pose and one landmark, in the state's order (ξ_x, ξ_y, ξ_θ, ξ_mx, ξ_my).
XI = sp.symbols("xi_x xi_y xi_theta xi_mx xi_my", real=True)
#: A Cartesian pose noise (n_x, n_y, n_θ) added after the step, and a measurement noise.
NOISE = sp.symbols("n_x n_y n_theta", real=True)
DZ = sp.symbols("dz_r dz_phi", real=True)
STATE = (*POSE, *LANDMARK)


def _rot(a: sp.Expr) -> sp.Matrix:
    return sp.Matrix([[sp.cos(a), -sp.sin(a)], [sp.sin(a), sp.cos(a)]])


def _V(a: sp.Expr) -> sp.Matrix:
    """SO(2)'s left Jacobian, (sin a / a) I + ((1 - cos a) / a) J, to first order: I + (a/2) J.

    Every map below is differentiated once at ξ = 0, where V's higher terms (a², ...) have no
    first derivative: the expansion gives the exact Jacobians without the 0/0 of sin a / a.
    """
    return sp.Matrix([[1, -a / 2], [a / 2, 1]])


def retract(state: sp.Matrix, xi) -> sp.Matrix:
    """exp(ξ) X̂ for (x, y, θ, m_x, m_y): θ + ξ_θ, every point v -> R(ξ_θ) v + V(ξ_θ) ξ_v."""
    a, V, R = xi[2], _V(xi[2]), _rot(xi[2])
    p = R * sp.Matrix(state[0:2]) + V * sp.Matrix(xi[0:2])
    m = R * sp.Matrix(state[3:5]) + V * sp.Matrix(xi[3:5])
    return sp.Matrix([p[0], p[1], state[2] + a, m[0], m[1]])


def _V_inv(a: sp.Expr) -> sp.Matrix:
    """V(a)⁻¹ to first order, I - (a/2) J (see `_V`)."""
    return sp.Matrix([[1, a / 2], [-a / 2, 1]])


def log_error(true: sp.Matrix, estimate: sp.Matrix) -> sp.Matrix:
    """ξ with true = exp(ξ) estimate: ξ_θ = θ - θ̂, ξ_v = V(ξ_θ)⁻¹ (v - R(ξ_θ) v̂)."""
    a = true[2] - estimate[2]
    Vi, R = _V_inv(a), _rot(a)
    p = Vi * (sp.Matrix(true[0:2]) - R * sp.Matrix(estimate[0:2]))
    m = Vi * (sp.Matrix(true[3:5]) - R * sp.Matrix(estimate[3:5]))
    return sp.Matrix([p[0], p[1], a, m[0], m[1]])


def _at_zero(expr: sp.Matrix, wrt) -> sp.ImmutableMatrix:
    """∂expr/∂wrt at ξ = 0 and the noises 0, simplified."""
    J = expr.jacobian(sp.Matrix(wrt)).subs({s: 0 for s in (*XI, *NOISE, *DZ)})
    return sp.ImmutableMatrix(J.applyfunc(sp.simplify))


def _moved(state: sp.Matrix, noise=(0, 0, 0)) -> sp.Matrix:
    f = motion_model().value  # eq. (6) in POSE and CONTROL
    pose = f.subs(dict(zip(POSE, state[0:3], strict=True)), simultaneous=True)
    return sp.Matrix([pose[0] + noise[0], pose[1] + noise[1], pose[2] + noise[2], *state[3:5]])


@cache
def propagation_jacobian() -> sp.ImmutableMatrix:
    """∂ξ'/∂ξ at 0 for ξ' = log(f(exp(ξ) X̂) f(X̂)⁻¹): the 5x5 identity."""
    X = sp.Matrix(STATE)
    return _at_zero(log_error(_moved(retract(X, XI)), _moved(X)), XI)


@cache
def propagation_noise_jacobian() -> sp.ImmutableMatrix:
    """∂ξ'/∂n at 0 (5x3): a Cartesian pose noise n after the step in invariant coordinates."""
    X = sp.Matrix(STATE)
    return _at_zero(log_error(_moved(X, NOISE), _moved(X)), NOISE)


@cache
def observation_jacobian() -> sp.ImmutableMatrix:
    """∂ẑ(exp(ξ) X̂)/∂ξ at 0 (2x5): eq. (14)'s blocks with a zero heading column."""
    h = observation_model().value  # eq. (13), with atan2
    true = retract(sp.Matrix(STATE), XI)
    moved = h.subs(dict(zip(STATE, true, strict=True)), simultaneous=True)
    return _at_zero(moved, XI)


@cache
def new_landmark_jacobians() -> tuple[sp.ImmutableMatrix, sp.ImmutableMatrix]:
    """(∂ξ_m/∂ξ_pose (2x3), ∂ξ_m/∂δz (2x2)) at 0 for a landmark placed by eq. (12).

    ξ_m = V(ξ_θ)⁻¹ (m(exp(ξ) pose, z + δz) - R(ξ_θ) m̂): the first is [I | 0], the second is
    eq. (12)'s ∂m/∂z.
    """
    g = inverse_observation_model().value
    X = sp.Matrix([*POSE, 0, 0])
    true_pose = retract(X, (*XI[:3], 0, 0))[:3]
    subs = dict(
        zip(
            (*POSE, *MEASUREMENT),
            (*true_pose, MEASUREMENT[0] + DZ[0], MEASUREMENT[1] + DZ[1]),
            strict=True,
        )
    )
    m_true = g.subs(subs, simultaneous=True)
    a = XI[2]
    xi_m = _V_inv(a) * (m_true - _rot(a) * g)
    return _at_zero(xi_m, XI[:3]), _at_zero(xi_m, DZ)


@dataclass(frozen=True)
class InvariantNumeric:
    """The derived Jacobians as numpy functions of (pose, landmark[, control]) or (pose, z)."""

    F: Callable[..., np.ndarray]  # (pose, landmark, u) -> 5x5
    noise: Callable[..., np.ndarray]  # (pose, landmark, u) -> 5x3, at the pose after the step
    H: Callable[..., np.ndarray]  # (pose, landmark) -> 2x5
    G_pose: Callable[..., np.ndarray]  # (pose, z) -> 2x3
    G_z: Callable[..., np.ndarray]  # (pose, z) -> 2x2


@cache
def invariant_numeric() -> InvariantNumeric:
    def lam(args, expr):
        f = sp.lambdify(args, expr, "numpy")
        return lambda *values: np.array(f(*values), dtype=float).reshape(expr.shape)

    F = lam([*STATE, *CONTROL], propagation_jacobian())
    N = lam([*STATE, *CONTROL], propagation_noise_jacobian())
    H = lam(STATE, observation_jacobian())
    Gp, Gz = (lam([*POSE, *MEASUREMENT], J) for J in new_landmark_jacobians())
    return InvariantNumeric(
        F=lambda pose, m, u: F(*pose, *m, *u),
        noise=lambda pose, m, u: N(*pose, *m, *u),
        H=lambda pose, m: H(*pose, *m),
        G_pose=lambda pose, z: Gp(*pose, *z),
        G_z=lambda pose, z: Gz(*pose, *z),
    )
