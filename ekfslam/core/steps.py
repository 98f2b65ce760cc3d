"""One EKF prediction (eqs. 6-9), one new landmark (eq. 12) and one correction (eqs. 13-16) on a
state held as plain arrays: the filter's own steps, as a notebook calls them.

Each function copies μ and Σ into storage of the filter's kind, runs the step the filter runs
(`ekfslam.core.filter.steps`, in block form, as Python) and hands back new arrays, so a reader
who steps through these steps through the filter. `update_steps` also hands back every
intermediate of the correction (H, K, and eq. (16) as the seed prints it beside Joseph's form)
for display; the literal F_x,j reference (`ekfslam.teaching.reference`) is tested against them.

The block form is Solà's (slamtb): an observation of landmark j sees only the robot's rows
r = 0:3 and the landmark's rows l = 3+2j : 5+2j, so eq. (14)'s H = [H_r  H_l] F_x,j touches two
column blocks of Σ, and Σ Hᵀ = Σ[:, r] H_rᵀ + Σ[:, l] H_lᵀ costs O(n) instead of the lift's
O(n²) products.

With ``invariant=True`` each step is the right-invariant EKF's (Barrau & Bonnabel 2015,
`ekfslam.core.invariant`), on the covariance P of the invariant error ξ: the prediction's
Jacobian is I and its noise A R Aᵀ reaches every row; H is eq. (14)'s times the error map; the
mean moves by the group exponential; a new landmark's ξ is ξ_p + G_z δz.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter import steps
from ekfslam.core.filter.history import OBS_NIS, Outcome, obs_width

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class UpdateSteps:
    """Every intermediate of one correction, eqs. (13)-(16), for a state of size d = 3 + 2n.

    z_hat (2,) eq. (13); nu (2,) innovation z - ẑ, bearing wrapped; H (2, d) eq. (14), zero
    outside the robot's and the landmark's columns; S (2, 2) innovation covariance H Σ Hᵀ + Q;
    K (d, 2) eq. (15); nis νᵀ S⁻¹ ν; mu_prior / mu_post (d,) eq. (16); Sigma_prior,
    Sigma_seed = (I - KH) Σ as printed in eq. (16), Sigma_joseph = (I - KH) Σ (I - KH)ᵀ + K Q Kᵀ
    (what the filter computes, as Σ - K S Kᵀ), all (d, d).
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


def _storage(mu: Array, Sigma: Array, size: int, invariant: bool) -> steps.Storage:
    """The filter's storage holding μ and Σ, with room for `size` rows."""
    lin = steps.Linearization.INVARIANT if invariant else steps.Linearization.STANDARD
    s = steps.Storage(np.zeros(size), np.zeros((size, size)), np.zeros(size), np.zeros(2), lin)
    d = len(mu)
    s.mu[:d], s.Sigma[:d, :d], s.first[:d] = mu, Sigma, mu
    return s


def _arrays(storage: steps.Storage, d: int) -> tuple[Array, Array]:
    """μ and Σ out of the storage (copies)."""
    steps.settle(storage, d)
    return storage.mu[:d].copy(), storage.Sigma[:d, :d].copy()


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
    z, Q = np.array(z, dtype=float), np.array(Q, dtype=float)
    d = len(mu)
    if not 0 <= j < (d - 3) // 2:
        raise ValueError(f"landmark slot {j} is not in a state of {(d - 3) // 2} landmarks")
    r, l = slice(0, 3), slice(3 + 2 * j, 5 + 2 * j)  # the robot's rows, landmark j's rows
    s = _storage(mu, Sigma, d, invariant)
    point = np.concatenate([mu[r], mu[l]])
    obs = np.full(obs_width(len(z)), math.nan)
    outcome = steps.correct(s, d, l.start, steps.Update(z, Q, math.inf, point), obs)
    if outcome != Outcome.ACCEPTED:
        raise ValueError(f"the correction was {Outcome(outcome).label}, not accepted")
    mu_post, Sigma_post = _arrays(s, d)
    H_r, H_l = steps.jacobians(s, point)  # eq. (14), in the filter's error
    H = np.zeros((len(z), d))
    H[:, r], H[:, l] = H_r, H_l
    S = H @ Sigma @ H.T + Q
    K = Sigma @ H.T @ np.linalg.inv(S)  # eq. (15)
    z_hat = steps.sensor.h(mu[r], mu[l])
    return UpdateSteps(
        j=j,
        z=z,
        z_hat=z_hat,
        nu=steps.sensor.innovation(z, z_hat),
        H=H,
        S=S,
        K=K,
        nis=float(obs[OBS_NIS]),
        mu_prior=mu,
        mu_post=mu_post,
        Sigma_prior=Sigma,
        Sigma_seed=Sigma - K @ H @ Sigma,
        Sigma_joseph=Sigma_post,
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
    d = len(mu)
    s = _storage(mu, np.array(Sigma, dtype=float), d, invariant)
    one = np.zeros(1)
    batch = steps.Batch(
        np.array(u, dtype=float).reshape(1, -1), one, one, np.array(R, float), False
    )
    steps.predict(s, d, batch, np.zeros((0, 10)))
    return _arrays(s, d)


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
    d = len(mu)
    s = _storage(mu, np.asarray(Sigma, dtype=float), d + 2, invariant)
    update = steps.Update(np.asarray(z, dtype=float), np.asarray(Q, dtype=float), math.inf, mu)
    steps.place_landmark(s, d + 2, d, update, 0.0)
    return _arrays(s, d + 2)
