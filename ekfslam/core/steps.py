"""One EKF prediction (eqs. 6-9), one new landmark (eq. 12) and one correction (eqs. 13-16) in
block form: the readable statement of each step.

The filter's compiled kernel (`ekfslam.core.filter.kernels.correct`) and the literal F_x,j
reference (`ekfslam.teaching.reference`) compute the same numbers; the tests hold both to this
one (tests/core/test_steps.py). The observation model and its Jacobian blocks are
`ekfslam.core.models.observation` and `observation_jacobians`, not derived again here.

The block form is Solà's (slamtb): an observation of landmark j sees only the robot's rows
r = 0:3 and the landmark's rows l = 3+2j : 5+2j, so eq. (14)'s H = [H_r  H_l] F_x,j touches two
column blocks of Σ, and Σ Hᵀ = Σ[:, r] H_rᵀ + Σ[:, l] H_lᵀ costs O(n) instead of the lift's
O(n²) products.

With ``invariant=True`` each step is the right-invariant EKF's (Barrau & Bonnabel 2015,
`ekfslam.core.invariant`), on the covariance P of the invariant error ξ: the prediction's
Jacobian is I and its noise A R Aᵀ reaches every row (O(n²)); H's heading column is zero; the
mean moves by the group exponential; a new landmark's ξ is ξ_p + G_z δz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.invariant import INVARIANT_NEW_LANDMARK_POSE, noise_map, retract
from ekfslam.core.models import (
    inverse_observation,
    inverse_observation_jacobians,
    motion,
    motion_jacobian,
    observation,
    observation_jacobians,
)
from ekfslam.geometry import wrap_angle

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class UpdateSteps:
    """Every intermediate of one correction, eqs. (13)-(16), for a state of size d = 3 + 2n.

    z_hat (2,) eq. (13); nu (2,) innovation z - ẑ, bearing wrapped; H (2, d) eq. (14), zero
    outside the robot's and the landmark's columns; S (2, 2) innovation covariance H Σ Hᵀ + Q;
    K (d, 2) eq. (15); nis νᵀ S⁻¹ ν; mu_prior / mu_post (d,) eq. (16); Sigma_prior,
    Sigma_seed = (I - KH) Σ as printed in eq. (16), Sigma_joseph = (I - KH) Σ (I - KH)ᵀ + K Q Kᵀ,
    all (d, d).
    """

    j: int
    z: Array
    z_hat: Array
    nu: Array
    H: Array
    S: Array
    K: Array
    nis: float
    mu_prior: Array
    mu_post: Array
    Sigma_prior: Array
    Sigma_seed: Array
    Sigma_joseph: Array


def update_steps(
    mu: ArrayLike, Sigma: ArrayLike, j: int, z: ArrayLike, Q: ArrayLike, invariant: bool = False
) -> UpdateSteps:
    """One EKF correction with landmark slot j, eqs. (13)-(16), on the blocks it touches.

    Parameters
    ----------
    mu : (d,) prior mean, eq. (1), d = 3 + 2n; Sigma : (d, d) its covariance.
    j : the landmark's slot (0-based; indices 3+2j, 4+2j).
    z : (2,) measured range (m) and bearing (rad), eq. (10); Q : (2, 2) eq. (11).
    """
    mu = np.array(mu, dtype=float)
    Sigma = np.array(Sigma, dtype=float)
    z = np.asarray(z, dtype=float)
    Q = np.asarray(Q, dtype=float)
    d = len(mu)
    if not 0 <= j < (d - 3) // 2:
        raise ValueError(f"landmark slot {j} is not in a state of {(d - 3) // 2} landmarks")
    r, l = slice(0, 3), slice(3 + 2 * j, 5 + 2 * j)  # the robot's rows, landmark j's rows
    z_hat = observation(mu[r], mu[l])  # eq. (13), with atan2
    H_r, H_l = observation_jacobians(mu[r], mu[l])  # eq. (14)'s two non-zero blocks
    if invariant:  # in ξ the bearing does not see the heading: H_r = [-H_l | 0]
        H_r = H_r.copy()
        H_r[:, 2] = 0.0
    SigmaHt = Sigma[:, r] @ H_r.T + Sigma[:, l] @ H_l.T  # Σ Hᵀ, (d, 2)
    S = H_r @ SigmaHt[r] + H_l @ SigmaHt[l] + Q  # H Σ Hᵀ + Q
    K = SigmaHt @ np.linalg.inv(S)  # eq. (15)
    nu = z - z_hat
    nu[1] = wrap_angle(float(nu[1]))
    mu_post = retract(mu, K @ nu) if invariant else mu + K @ nu  # eq. (16)
    mu_post[2] = wrap_angle(float(mu_post[2]))
    H = np.zeros((2, d))
    H[:, r], H[:, l] = H_r, H_l
    KHSigma = K @ SigmaHt.T  # K H Σ, with H Σ = (Σ Hᵀ)ᵀ
    return UpdateSteps(
        j=j,
        z=z.copy(),
        z_hat=z_hat,
        nu=nu,
        H=H,
        S=S,
        K=K,
        nis=float(nu @ np.linalg.solve(S, nu)),
        mu_prior=mu,
        mu_post=mu_post,
        Sigma_prior=Sigma,
        Sigma_seed=Sigma - KHSigma,
        # Joseph's form expanded: (I-KH)Σ(I-KH)ᵀ + KQKᵀ = Σ - KHΣ - (KHΣ)ᵀ + K S Kᵀ
        Sigma_joseph=Sigma - KHSigma - KHSigma.T + K @ S @ K.T,
    )


def predict_step(
    mu: ArrayLike, Sigma: ArrayLike, u: ArrayLike, R: ArrayLike, invariant: bool = False
) -> tuple[Array, Array]:
    """One EKF prediction, eqs. (6), (7) and (9) done right, on the blocks it touches.

    The motion moves only the robot (rows r = 0:3); the landmarks m = 3: stay. With the 3x3 G of
    eq. (7), evaluated at the pose *before* the motion, the lifted eq. (9) is
    Σ[r, r] = G Σ[r, r] Gᵀ + R,  Σ[r, m] = G Σ[r, m],  Σ[m, r] = Σ[r, m]ᵀ,  Σ[m, m] unchanged.

    Parameters
    ----------
    mu : (d,) mean, d = 3 + 2n; Sigma : (d, d); u : (3,) control increment (eq. 4, body frame);
    R : (3, 3) motion noise in the state's coordinates (R = V M Vᵀ, Thrun's and the seed's R).

    Returns
    -------
    (mu, Sigma) : new arrays (d,) and (d, d); the heading is wrapped to [-π, π).
    """
    mu = np.array(mu, dtype=float)
    Sigma = np.array(Sigma, dtype=float)
    r, m = slice(0, 3), slice(3, None)
    G = motion_jacobian(mu[r], u)
    mu[r] = motion(mu[r], u)
    if invariant:  # Σ (that is P) + A R Aᵀ, A = noise_map at the new state: every row moves
        A = noise_map(mu)
        return mu, Sigma + A @ np.asarray(R, dtype=float) @ A.T
    Sigma[r, r] = G @ Sigma[r, r] @ G.T + np.asarray(R, dtype=float)
    Sigma[r, m] = G @ Sigma[r, m]
    Sigma[m, r] = Sigma[r, m].T
    return mu, Sigma


def new_landmark_step(
    mu: ArrayLike, Sigma: ArrayLike, z: ArrayLike, Q: ArrayLike, invariant: bool = False
) -> tuple[Array, Array]:
    """A landmark first seen at z = (r, φ) appended to the state, eq. (12), with its covariance.

    With the Jacobians G_p = ∂m/∂pose (2x3) and G_z = ∂m/∂z (2x2) of eq. (12), the new rows
    l = d : d+2 are Σ[l, l] = G_p Σ[r, r] G_pᵀ + G_z Q G_zᵀ and the cross-covariance with the
    whole old state Σ[l, :d] = G_p Σ[r, :d] (the robot *and* the landmarks already in the map);
    `FilterConfig(init="inverse")`, the filter's default.

    Parameters
    ----------
    mu : (d,); Sigma : (d, d); z : (2,) range (m) and bearing (rad); Q : (2, 2), eq. (11).

    Returns
    -------
    (mu, Sigma) : new arrays (d+2,) and (d+2, d+2).
    """
    mu = np.asarray(mu, dtype=float)
    Sigma = np.asarray(Sigma, dtype=float)
    d, r = mu.size, slice(0, 3)
    G_p, G_z = inverse_observation_jacobians(mu[r], z)
    if invariant:
        G_p = INVARIANT_NEW_LANDMARK_POSE
    cross = G_p @ Sigma[r, :]  # (2, d)
    new = np.zeros((d + 2, d + 2))
    new[:d, :d] = Sigma
    new[d:, :d] = cross
    new[:d, d:] = cross.T
    new[d:, d:] = G_p @ Sigma[r, r] @ G_p.T + G_z @ np.asarray(Q, dtype=float) @ G_z.T
    return np.concatenate([mu, inverse_observation(mu[r], z)]), new
