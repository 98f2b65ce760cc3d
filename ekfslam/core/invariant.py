"""The right-invariant error of EKF SLAM on SE_{1+n}(2), and the maps to and from Cartesian.

Barrau & Bonnabel, "An EKF-SLAM algorithm with consistency properties" (2015; arXiv:1510.06263)
write the state of eq. (1) as one matrix group element, SE_{1+n}(2):

    X = [[R(θ), p, m_1, ..., m_n],
         [0,    1, 0,   ..., 0  ],  ...]   (the identity below the first two rows)

and the error as the right-invariant η = X X̂⁻¹ = exp(ξ). To first order, with J = [[0, -1], [1, 0]]
(a quarter turn), the true state is

    θ = θ̂ + ξ_θ,   p = p̂ + ξ_p + J p̂ ξ_θ,   m_i = m̂_i + ξ_mi + J m̂_i ξ_θ,

so the Cartesian error δ = (δx, δy, δθ, δm) of the other filters is δ = T(μ̂) ξ with
T = I + c e₃ᵀ, c = (J p̂, 0, J m̂_1, ..., J m̂_n): a global rotation of the whole map about the
origin, the unobservable direction, is ξ = e₃ whatever the estimate. In ξ the motion of eq. (6)
is group-affine, so the propagation Jacobian is the identity, and the observation Jacobian of
eq. (14) loses its heading column (see `ekfslam.teaching.invariant`, which derives both).

The invariant filter keeps the covariance P of ξ (ordered as the state: ξ_x, ξ_y, ξ_θ, ξ_m...),
and reports Σ = T P Tᵀ, the first-order Cartesian covariance, wherever a covariance leaves it
(ellipses, NEES, the history): everything downstream reads one kind of covariance.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.geometry import rotation, wrap_angle

Array = NDArray[np.float64]

#: ∂ξ_m/∂ξ_pose of a landmark initialised by eq. (12): ξ_m = ξ_p + G_z δz, no heading term.
INVARIANT_NEW_LANDMARK_POSE = np.array(((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)))
INVARIANT_NEW_LANDMARK_POSE.flags.writeable = False


def rotation_column(mu: ArrayLike) -> Array:
    """c = (J p̂, 0, J m̂_1, ...) (d,): the Cartesian error of the rotation ξ = e₃ (without its e₃).

    Written for plain numpy and for numba alike: the filter's compiled steps call it too.
    """
    c = np.empty(len(mu))
    c[0], c[1], c[2] = -mu[1], mu[0], 0.0
    c[3::2] = -mu[4::2]
    c[4::2] = mu[3::2]
    return c


def error_map(mu: ArrayLike) -> Array:
    """T(μ̂) (d, d): the Cartesian error δ = T ξ of a small invariant error ξ at the estimate μ̂."""
    c = rotation_column(np.asarray(mu, dtype=np.float64))
    T = np.eye(len(c))
    T[:, 2] += c
    return T


def to_cartesian(P: ArrayLike, mu: ArrayLike) -> Array:
    """Σ = T P Tᵀ (a new array): the Cartesian covariance of an invariant one P, O(d²)."""
    P = np.asarray(P, dtype=np.float64)
    c = rotation_column(np.asarray(mu, dtype=np.float64)[: len(P)])
    p2 = P[:, 2]
    return P + np.outer(c, p2) + np.outer(p2, c) + P[2, 2] * np.outer(c, c)


def from_cartesian(Sigma: ArrayLike, mu: ArrayLike) -> Array:
    """P = T⁻¹ Σ T⁻ᵀ, with T⁻¹ = I - c e₃ᵀ: the invariant covariance of a Cartesian one."""
    Sigma = np.asarray(Sigma, dtype=np.float64)
    c = -rotation_column(np.asarray(mu, dtype=np.float64)[: len(Sigma)])
    s2 = Sigma[:, 2]
    return Sigma + np.outer(c, s2) + np.outer(s2, c) + Sigma[2, 2] * np.outer(c, c)


def landmark_to_cartesian(P_mm: ArrayLike, P_mtheta: ArrayLike, P_thth: float, m: ArrayLike):
    """One landmark's 2x2 Cartesian covariance from its invariant blocks (δm = ξ_m + J m̂ ξ_θ)."""
    g = np.array((-m[1], m[0]))
    return P_mm + np.outer(g, P_mtheta) + np.outer(P_mtheta, g) + P_thth * np.outer(g, g)


def noise_map(mu: ArrayLike) -> Array:
    """A (d, 3) = T(μ̂)⁻¹ F_xᵀ: a Cartesian pose noise n at the estimate μ̂ is A n in ξ.

    ξ_p = n_p - J p̂ n_θ, ξ_θ = n_θ, and ξ_m = -J m̂ n_θ for every landmark: in the invariant
    error a heading noise turns the whole map about the robot's frame (Barrau & Bonnabel's
    Ad_X̂), so the noise reaches every row of P, not only the pose's.
    """
    c = rotation_column(np.asarray(mu, dtype=np.float64))
    A = np.zeros((len(c), 3))
    A[:3] = np.eye(3)
    A[:, 2] -= c
    return A


def so2_left_jacobian(phi: float) -> Array:
    """V(φ) = (sin φ / φ) I + ((1 - cos φ) / φ) J, the translation part of SE(2)'s exponential."""
    if abs(phi) < 1e-6:  # the series of sin φ / φ and (1 - cos φ) / φ
        a, b = 1.0 - phi * phi / 6.0, 0.5 * phi
    else:
        a, b = math.sin(phi) / phi, (1.0 - math.cos(phi)) / phi
    return np.array(((a, -b), (b, a)))


def retract(mu: ArrayLike, xi: ArrayLike) -> Array:
    """exp(ξ) X̂ as a state vector: θ + ξ_θ, and each point v -> R(ξ_θ) v + V(ξ_θ) ξ_v.

    The invariant filter's correction of eq. (16): μ̂ <- exp(K ν) μ̂ instead of μ̂ + K ν. The
    heading is wrapped to [-π, π). Plain numpy and numba alike (the filter compiles it).
    """
    w = xi[2]
    R, V = rotation(w), so2_left_jacobian(w)
    out = np.empty(len(mu))
    out[0:2] = R @ mu[0:2] + V @ xi[0:2]
    out[2] = wrap_angle(mu[2] + w)
    for i in range(3, len(mu), 2):
        out[i : i + 2] = R @ mu[i : i + 2] + V @ xi[i : i + 2]
    return out


def pose_error(truth: ArrayLike, estimate: ArrayLike) -> Array:
    """ξ (K, 3) = log(X X̂⁻¹) of the pose part, exactly: the invariant error of `retract`.

    truth, estimate : (K, 3) poses (x, y, θ). ξ_θ = θ - θ̂ (wrapped to [-π, π)) and
    ξ_p = V(ξ_θ)⁻¹ (p - R(ξ_θ) p̂), so that the truth is exp(ξ) X̂ (`retract`). To first order
    ξ = T(μ̂)⁻¹ δ with δ the Cartesian error: this is the error that the invariant filter's
    covariance P describes, and the one Barrau & Bonnabel (2015) score their NEES with.
    """
    p = np.asarray(truth, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(estimate, dtype=np.float64).reshape(-1, 3)
    w = wrap_angle(p[:, 2] - q[:, 2])
    c, s = np.cos(w), np.sin(w)
    dx = p[:, 0] - (c * q[:, 0] - s * q[:, 1])
    dy = p[:, 1] - (s * q[:, 0] + c * q[:, 1])
    # V(w)⁻¹ = (w / 2) [[cot(w/2), 1], [-1, cot(w/2)]], with w/2 cot(w/2) -> 1 - w²/12 at 0
    small = np.abs(w) < 1e-6
    half = 0.5 * w
    a = np.where(small, 1.0 - w * w / 12.0, half / np.tan(np.where(small, 1.0, half)))
    return np.column_stack([a * dx + half * dy, -half * dx + a * dy, w])
