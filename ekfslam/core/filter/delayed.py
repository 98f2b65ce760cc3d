"""The held first sightings of a sensor that needs two (a bearing alone), and the clones of the
poses they were made from: Bailey's delayed initialisation (`ekfslam.core.initialisation`).

While a sighting is held, the pose it was made from is part of the state: the state is then
(x, c_1, ..., c_h), x the filter's μ (3 + 2n) and each clone c_i a copy of the pose (3,) at its
sighting. The filter's storage keeps x; `Clones` keeps the clones' rows of the augmented state
beside it, changed exactly as those rows would be (first order, as every EKF step):

    c (h, 3) the clones' means; C (3h, d) Cov(c, x); P (3h, 3h) Cov(c, c).

- a clone is made at a first sighting: c_new = p, Cov(c_new, x) = Σ[r, :], Cov(c_new, c_i) =
  Cov(p, c_i), Cov(c_new, c_new) = Σ[r, r];
- a prediction moves only x's pose (eq. 9 on the augmented state): C[:, r] ← C[:, r] G_allᵀ,
  G_all the product of the batch's G's (eq. 7), P unchanged;
- a correction of x (eqs. 15-16) corrects the clones too, with their own gain U S⁻¹,
  U = C Hᵀ = C[:, r] H_rᵀ + C[:, L] H_lᵀ: c += U S⁻¹ ν, C -= U S⁻¹ H Σ, P -= U S⁻¹ Uᵀ;
- a landmark placed by its two sightings (`place`) gets Σ[L, :] = G_b Σ[r, :] + G_a C_i, and
  the other clones their Cov with it, C_k[:, L] = C_k[:, r] G_bᵀ + P_ki G_aᵀ; its clone is then
  marginalised (its rows dropped).

The filter calls these only while a sighting is held (Python, O(h n) a step, whatever the
backend): with the standard linearisation and one linearisation per update (`FilterConfig`
refuses the others for such a sensor).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.initialisation import Held, Placement, too_spread
from ekfslam.core.models import MotionModel, SensorModel

Array = NDArray[np.float64]


class Clones:
    """The held sightings, by landmark id, and their clones' rows (see the module)."""

    def __init__(self) -> None:
        self.ids: list[int] = []
        self.sightings: list[tuple[Array, Array]] = []  # each held one's z and Q
        self.c = np.zeros((0, 3))
        self.C = np.zeros((0, 0))
        self.P = np.zeros((0, 0))

    def __len__(self) -> int:
        return len(self.ids)

    def copy(self) -> Clones:
        other = Clones()
        other.ids, other.sightings = list(self.ids), list(self.sightings)
        other.c, other.C, other.P = self.c.copy(), self.C.copy(), self.P.copy()
        return other

    def held(self, landmark_id: int) -> Held | None:
        """The held sighting of this landmark, its pose the clone's current estimate, or None."""
        if landmark_id not in self.ids:
            return None
        i = self.ids.index(landmark_id)
        z, Q = self.sightings[i]
        return Held(self.c[i].copy(), z, Q)

    def hold(self, landmark_id: int, z: Array, Q: Array, mu: Array, Sigma: Array, d: int) -> None:
        """Hold a first sighting (replacing one held for the id), cloning the pose."""
        if landmark_id in self.ids:
            self.drop(landmark_id)
        h = len(self.ids)
        C = np.zeros((3 * h + 3, d))
        C[: 3 * h] = self.C[:, :d] if h else 0.0
        C[3 * h :] = Sigma[:3, :d]
        P = np.zeros((3 * h + 3, 3 * h + 3))
        P[: 3 * h, : 3 * h] = self.P
        P[3 * h :, : 3 * h] = self.C[:, :3].T if h else 0.0  # Cov(p, c_i)
        P[: 3 * h, 3 * h :] = P[3 * h :, : 3 * h].T
        P[3 * h :, 3 * h :] = Sigma[:3, :3]
        self.ids.append(landmark_id)
        self.sightings.append((np.array(z, dtype=float), np.array(Q, dtype=float)))
        self.c = np.vstack((self.c, mu[:3]))
        self.C, self.P = C, P

    def drop(self, landmark_id: int) -> None:
        """Marginalise a clone: its rows dropped from the augmented state."""
        i = self.ids.index(landmark_id)
        keep = np.array([k for k in range(3 * len(self.ids)) if k // 3 != i], dtype=np.int64)
        del self.ids[i], self.sightings[i]
        self.c = np.delete(self.c, i, axis=0)
        self.C, self.P = self.C[keep], self.P[np.ix_(keep, keep)]

    def predict(self, motion: MotionModel, pose: Array, batch: tuple) -> None:
        """A prediction batch (`ekfslam.core.filter.steps.Batch`) from `pose`, before it:
        C[:, r] ← C[:, r] G_allᵀ, G_all the product of eq. (7)'s G at each step's start pose."""
        us, dts = batch[0], batch[1]
        pose, G_all = np.array(pose, dtype=float), np.eye(3)
        for u, dt in zip(us, dts, strict=True):
            G_all = motion.F_x(pose, u, dt) @ G_all
            pose = motion.f(pose, u, dt)
        self.C[:, :3] = self.C[:, :3] @ G_all.T

    def before_correction(
        self, sensor: SensorModel, mu: Array, Sigma: Array, d: int, l: int, z: Array, Q: Array
    ) -> tuple[Array, Array, Array, Array]:
        """What a correction of the landmark at rows l, l+1 needs of the clones, from the state
        before it: (H Σ (m, d), S (m, m), ν (m,), U = C Hᵀ (3h, m)), H at the estimate."""
        r, L = slice(0, 3), slice(l, l + 2)
        H_r, H_l = sensor.H(mu[r], mu[L])
        HSigma = H_r @ Sigma[r, :d] + H_l @ Sigma[L, :d]
        S = HSigma[:, r] @ H_r.T + HSigma[:, L] @ H_l.T + Q
        nu = sensor.innovation(z, sensor.h(mu[r], mu[L]))
        U = self.C[:, r] @ H_r.T + self.C[:, L] @ H_l.T
        return HSigma, S, nu, U

    def corrected(self, before: tuple[Array, Array, Array, Array]) -> None:
        """The clones after an accepted correction (eqs. 15-16 on their rows)."""
        HSigma, S, nu, U = before
        X = np.linalg.solve(S, U.T).T  # U S⁻¹, the clones' gain
        self.c += (X @ nu).reshape(-1, 3)
        self.C[:, : HSigma.shape[1]] -= X @ HSigma
        P = self.P - X @ U.T
        self.P = 0.5 * (P + P.T)

    def place(
        self,
        landmark_id: int,
        placement: Placement,
        Sigma: Array,
        d: int,
        pose: Array,
        max_spread: float,
    ) -> Array | None:
        """The rows (2, d + 2) of the landmark its two sightings place at rows d, d+1 (Σ[L, :],
        its own block included; see the module), the other clones given their covariance with it,
        and its clone marginalised; or None, nothing changed, when its covariance is too spread
        for the linearisation (`ekfslam.core.initialisation.too_spread`: wait for more parallax)."""
        i = self.ids.index(landmark_id)
        G_a, G_b = placement.G_a, placement.G_b
        C_i, P_ii = self.C[3 * i : 3 * i + 3, :d], self.P[3 * i : 3 * i + 3, 3 * i : 3 * i + 3]
        rows = np.zeros((2, d + 2))
        rows[:, :d] = G_b @ Sigma[:3, :d] + G_a @ C_i
        cross = G_b @ C_i[:, :3].T @ G_a.T  # G_b Σ[r, c] G_aᵀ
        own = G_b @ Sigma[:3, :3] @ G_b.T + G_a @ P_ii @ G_a.T + cross + cross.T
        own += placement.L @ placement.Q @ placement.L.T
        rows[:, d:] = 0.5 * (own + own.T)
        if too_spread(rows[:, d:], placement.landmark, pose, max_spread):
            return None
        C = np.zeros((self.C.shape[0], d + 2))
        C[:, :d] = self.C[:, :d]
        C[:, d:] = self.C[:, :3] @ G_b.T + self.P[:, 3 * i : 3 * i + 3] @ G_a.T
        self.C = C
        self.drop(landmark_id)
        return rows
