"""What the association asks of the filter: each mapped landmark's predicted observation, the
innovations of one time's sightings against each, and the covariances of those predictions.

`ekfslam.core.association` decides from these (``nn``, ``jcbb``, ``mht``); the filter owns Σ,
so it computes them (`ekfslam.core.filter.ekf.EKFSLAM.predictions`, `nearest`). Each landmark j
is seen through the sensor model (`ekfslam.core.models`): ẑ_j = h(pose, m_j) and H_j, eq. (14),
non-zero on the pose and on m_j only. So H_j Σ H_kᵀ needs just the 5x5 block of Σ on
(x, y, θ, m_j) x (x, y, θ, m_k) (`ekfslam.core.filter.symmetric.block`), never H's zeros:
O(m n) for ``nn``, O(n²) for the joint covariance ``jcbb`` needs.

Like the filter's steps, these take plain tuples laid out as the records name them, and run as
written or compiled (`ekfslam.core.filter.backend`).
The predictions use the current estimate, also under FEJ: the association is a test, not an
update. The invariant filter settles the heading noise it owes first (`steps.settle`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.filter.steps import Storage, apart, jacobians, sensor
from ekfslam.core.filter.symmetric import block

Array = NDArray[np.float64]


class Sightings(NamedTuple):
    """The sightings of one time: z (m, 2), and the noise Q (2, 2) they are tested with."""

    z: Array
    Q: Array


class Rate(NamedTuple):
    """How the robot moved when an image was taken, for its one time-stamp error
    (`ekfslam.core.timestamp`): velocity (2,) m/s in the body frame, omega rad/s, and variance
    s² of the error (0: none)."""

    velocity: Array
    omega: float
    variance: float


class Predicted(NamedTuple):
    """What `predict_all` fills in: nu (m, n, 2) the innovations z_i - ẑ_j; P (2n, 2n) the joint
    covariance H Σ Hᵀ of the n predictions; nis (m, n) each sighting's NIS against each."""

    nu: Array
    P: Array
    nis: Array


def indices(l: int) -> Array:
    """The state rows a landmark's observation depends on: the pose's and its own (5,)."""
    return np.array((0, 1, 2, l, l + 1))


def observed(storage: Storage, l: int) -> tuple[bool, Array, Array]:
    """Whether landmark l can be seen (it is off the robot), its ẑ (2,), and H (2, 5) on
    (pose, landmark), eq. (14), at the estimate."""
    mu = storage[0]
    point = np.concatenate((mu[:3], mu[l : l + 2]))
    if not apart(point[:3], point[3:]):
        return False, np.zeros(2), np.zeros((2, 5))
    H_r, H_l = jacobians(storage, point)
    return True, sensor.h(point[:3], point[3:]), np.hstack((H_r, H_l))


def nis_of(nu: Array, S: Array) -> float:
    """νᵀ S⁻¹ ν for a 2x2 S; inf when S is not positive definite or the result not finite."""
    det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    if not (S[0, 0] > 0.0 and det > 0.0):
        return math.inf
    value = (S[1, 1] * nu[0] ** 2 - 2.0 * S[1, 0] * nu[0] * nu[1] + S[0, 0] * nu[1] ** 2) / det
    return value if math.isfinite(value) else math.inf


def nearest(
    storage: Storage, d: int, sightings: Sightings, gate: float, pairing: Array, smallest: Array
) -> None:
    """Individual compatibility, O(m n): each sighting's smallest NIS over the landmarks into
    smallest (m,) (inf: none finite), and that landmark's index into pairing (m,) when its NIS
    is at most the gate, else -1 (ties: the lower index). The NIS of sighting i and landmark j
    is ν_ijᵀ S_j⁻¹ ν_ij with S_j = H_j Σ H_jᵀ + Q (`ekfslam.core.association.individual_nis`
    and `nearest_neighbour`, without H Σ Hᵀ for every pair)."""
    Sigma, (zs, Q) = storage[1], sightings
    pairing[:] = -1
    smallest[:] = math.inf
    for j in range((d - 3) // 2):
        l = 3 + 2 * j
        seen, z_hat, H = observed(storage, l)
        if not seen:
            continue
        S = H @ block(Sigma, indices(l), indices(l)) @ H.T + Q
        for i in range(zs.shape[0]):
            nis = nis_of(sensor.innovation(zs[i], z_hat), S)
            if nis < smallest[i]:
                smallest[i], pairing[i] = nis, j
    for i in range(zs.shape[0]):
        if not smallest[i] <= gate:
            pairing[i] = -1


def predict_all(storage: Storage, d: int, sightings: Sightings, rate: Rate, out: Predicted) -> None:
    """Fill `out` for the n = (d - 3) / 2 mapped landmarks and the m sightings.

    P_jk = H_j Σ H_kᵀ from the 5x5 blocks (see the module); with a time-stamp error
    (`Rate.variance` s² > 0), plus s² g_j g_kᵀ: every sighting of the image was taken from the
    pose at t + δt, off by u δt, u = (R(θ) v, ω) the pose's rate (eq. 6), so prediction j moves
    by g_j = H_pose,j u (eq. 14's Cartesian pose block, for the invariant filter too: δt moves
    the true pose), and a joint test allows a common shift of the image's bearings but not a
    relative one. A landmark on the robot gets an infinite NIS.
    """
    mu, Sigma = storage[0], storage[1]
    (zs, Q), (velocity, omega, variance), (nu, P, nis) = sightings, rate, out
    n, m = (d - 3) // 2, zs.shape[0]
    Hs = np.zeros((n, 2, 5))
    g = np.zeros((n, 2))
    seen = np.zeros(n, dtype=np.bool_)
    c, s = math.cos(mu[2]), math.sin(mu[2])
    u = np.array((c * velocity[0] - s * velocity[1], s * velocity[0] + c * velocity[1], omega))
    for j in range(n):
        l = 3 + 2 * j
        seen_j, z_hat, H = observed(storage, l)
        seen[j], Hs[j] = seen_j, H
        if seen[j] and variance > 0.0:
            g[j] = sensor.H(mu[:3], mu[l : l + 2])[0] @ u
        for i in range(m):
            nu[i, j] = sensor.innovation(zs[i], z_hat)
    for j in range(n):
        for k in range(j + 1):
            P_jk = Hs[j] @ block(Sigma, indices(3 + 2 * j), indices(3 + 2 * k)) @ Hs[k].T
            P_jk += variance * np.outer(g[j], g[k])
            P[2 * j : 2 * j + 2, 2 * k : 2 * k + 2] = P_jk
            P[2 * k : 2 * k + 2, 2 * j : 2 * j + 2] = P_jk.T
    for j in range(n):
        S = P[2 * j : 2 * j + 2, 2 * j : 2 * j + 2] + Q
        for i in range(m):
            nis[i, j] = nis_of(nu[i, j], S) if seen[j] else math.inf


def _sightings(zs, Q) -> Sightings:
    """zs (m, 2) and Q (2, 2) as the steps take them (C-ordered floats), Q's shape checked."""
    Q = np.ascontiguousarray(Q, dtype=float)
    if Q.shape != (2, 2):
        raise ValueError(f"observation noise must be 2x2, got shape {Q.shape}")
    return Sightings(np.ascontiguousarray(zs, dtype=float).reshape(-1, 2), Q)


def predictions_of(steps, arrays: tuple, d: int, zs, Q, rate: Rate | None = None) -> Predicted:
    """`predict_all` of the state in `arrays` (a `Storage` tuple, its first d rows the pose
    then the landmarks) by the step functions `steps` (`FilterState.steps`, compiled or not),
    into new arrays: `EKFSLAM.predictions`, and what a team's robot asks of the joint map
    (`ekfslam.core.filter.team.RobotView`)."""
    sightings = _sightings(zs, Q)
    m, n = len(sightings.z), (d - 3) // 2
    out = Predicted(np.empty((m, n, 2)), np.empty((2 * n, 2 * n)), np.empty((m, n)))
    rate = tuple(rate or Rate(np.zeros(2), 0.0, 0.0))
    steps.predict_all(arrays, d, tuple(sightings), rate, tuple(out))
    return out


def nearest_of(steps, arrays: tuple, d: int, zs, Q, gate: float) -> tuple[list[int], list[float]]:
    """`nearest` of the state in `arrays`, as `predictions_of` is `predict_all`: each
    sighting's landmark slot of smallest NIS within the gate (-1: none), and that NIS."""
    sightings = _sightings(zs, Q)
    pairing, smallest = np.empty(len(sightings.z), dtype=np.int64), np.empty(len(sightings.z))
    steps.nearest(arrays, d, tuple(sightings), float(gate), pairing, smallest)
    return pairing.tolist(), smallest.tolist()
