"""The seed's equations written literally, with the lift matrices F_x and F_x,j and full-size G, H.

This is a teaching artefact and the test oracle for `ekfslam.core.filter.ekf`: every product here is
(3 + 2n) wide, so a step costs O(n^3). Read it next to the report; never use it for real runs.

Where the seed's printed shapes are wrong (eqs. 7 and 9 write F_x R F_x^T, which is 3x3), this
uses the lift that type-checks: G = I + F_xᵀ (g - I) F_x and R lifted as F_xᵀ R F_x.
With `linearization="invariant"` it is Barrau & Bonnabel's right-invariant EKF (2015) written as
literally: `Sigma` is then the covariance of the invariant error ξ, the motion Jacobian is the
full-size identity, the observation Jacobian is eq. (14)'s lifted H times the full-size error map
T(μ̂) of `ekfslam.core.invariant` (H_ξ = H T), and the mean moves by the group exponential;
`cartesian_Sigma` is T Σ Tᵀ, what the fast filter reports.
With `iterations` > 1 the update is the iterated one of `ekfslam.core.filter.iterated`, each
linearisation full size (`_iterate`).
The covariance update is Joseph's form (I - KH) Σ (I - KH)ᵀ + K Q Kᵀ, which for the optimal gain
equals the seed's eq. (16) (I - KH) Σ but stays symmetric and positive semi-definite.
"""

from __future__ import annotations

from dataclasses import fields

import numpy as np
from numpy.typing import ArrayLike

from ekfslam.core.filter.config import FilterConfig, FilterCounts
from ekfslam.core.filter.history import Outcome
from ekfslam.core.initialisation import Held, too_spread, triangulated
from ekfslam.core.invariant import INVARIANT_NEW_LANDMARK_POSE, error_map, noise_map, retract
from ekfslam.core.models import MIN_RANGE_SQUARED, ODOMETRY, RANGE_BEARING
from ekfslam.geometry import wrap_angle
from ekfslam.teaching.derivations import landmark_lift_matrix_numeric, lift_matrix_numeric


class LiteralEKFSLAM:
    """Same interface as `ekfslam.core.filter.ekf.EKFSLAM` (predict, update, mu, Sigma,
    landmark_map)."""

    def __init__(
        self,
        pose: ArrayLike,
        pose_covariance: ArrayLike | None = None,
        config: FilterConfig | None = None,
    ) -> None:
        self.config = config or FilterConfig()
        self.mu = np.asarray(pose, dtype=float).copy()
        self.mu[2] = wrap_angle(float(self.mu[2]))
        self.Sigma = (
            np.zeros((3, 3)) if pose_covariance is None else np.array(pose_covariance, dtype=float)
        )
        self.slot: dict[int, int] = {}
        self._sightings: list[int] = []
        self._fej = self.config.linearization == "fej"
        self._invariant = self.config.linearization == "invariant"
        if self._invariant:  # Σ0 is given Cartesian: the invariant one is T⁻¹ Σ0 T⁻ᵀ
            T_inv = np.linalg.inv(error_map(self.mu))
            self.Sigma = T_inv @ self.Sigma @ T_inv.T
        self.motion = self.config.motion or ODOMETRY  # the models, as the filter takes them
        self.sensor = self.config.sensor or RANGE_BEARING
        self._prior = self.mu[:3].copy()  # FEJ: the pose predicted for the current step
        self._first: list[np.ndarray] = []  # FEJ: each landmark's first estimate
        self._rejected: list[list[np.ndarray]] = []  # per slot: rejected sightings' positions
        self._counts = dict.fromkeys((f.name for f in fields(FilterCounts)), 0)
        # a two-sighting sensor's held sightings (id -> z, Q) and their poses' clones: means
        # c (h, 3), Cov(c, x) C (3h, d), Cov(c, c) P (3h, 3h), Bailey's augmented state
        self._held: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._c, self._C, self._P = np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 0))

    @classmethod
    def from_state(
        cls, mu: ArrayLike, Sigma: ArrayLike, ids: list[int], config: FilterConfig | None = None
    ) -> LiteralEKFSLAM:
        """The reference holding a given state: mean (d,), covariance (d, d) (of ξ for the
        invariant filter) and the landmarks' ids in slot order, each seen once, its first
        estimate its mean. Growing one landmark at a time is itself O(n³) here."""
        mu = np.array(mu, dtype=float)
        lit = cls(mu[:3], None, config)
        lit.mu, lit.Sigma = mu, np.array(Sigma, dtype=float)
        lit.slot = {i: j for j, i in enumerate(ids)}
        lit._sightings = [1] * len(ids)
        lit._first = [mu[3 + 2 * j : 5 + 2 * j].copy() for j in range(len(ids))]
        lit._rejected = [[] for _ in ids]
        return lit

    @property
    def n_landmarks(self) -> int:
        return len(self.slot)

    @property
    def counts(self) -> FilterCounts:
        return FilterCounts(**self._counts)

    @property
    def cartesian_Sigma(self) -> np.ndarray:
        """The covariance of (x, y, θ, m): Sigma itself, or T Sigma Tᵀ for the invariant filter."""
        if not self._invariant:
            return self.Sigma
        T = error_map(self.mu)
        return T @ self.Sigma @ T.T

    def landmark_map(self) -> dict[int, np.ndarray]:
        return {i: self.mu[3 + 2 * j : 5 + 2 * j].copy() for i, j in self.slot.items()}

    def predict(
        self,
        u: ArrayLike,
        R: ArrayLike | None = None,
        t: float | None = None,
        *,
        dt: float = 0.0,
        M: ArrayLike | None = None,
    ) -> None:
        """Eqs. (6), (7), (9) with F_x (eq. 8), for a control u (k,) of the motion model over dt
        s; the noise a state-space R (3, 3), or a control covariance per second M (k, k) as
        `EKFSLAM.predict_many` takes it: R = V (M dt) Vᵀ with V = F_v(pose, u, dt) (3, k)."""
        n = self.n_landmarks
        F_x = lift_matrix_numeric(n)  # 3 x (2n+3)
        I = np.eye(3 + 2 * n)
        pose = self.mu[:3]
        u = np.asarray(u, dtype=float)
        if M is not None:
            V = self.motion.F_v(pose, u, dt)
            R = V @ (np.asarray(M, dtype=float) * dt) @ V.T
        predicted = self.motion.f(pose, u, dt)
        g = self.motion.F_x(pose, u, dt)
        if self._fej:  # eq. (7) at the predicted positions p̂(k+1|k) and p̂(k|k-1)
            g[0, 2] = -(predicted[1] - self._prior[1])
            g[1, 2] = predicted[0] - self._prior[0]
        self._prior = predicted.copy()
        G = I + F_x.T @ (g - np.eye(3)) @ F_x
        if self._held:  # the clones: Cov(c, G x) (the augmented state's G is I on c)
            self._C = self._C @ G.T
        noise = F_x.T  # how the pose noise enters the state's error
        step = predicted - pose
        step[2] = wrap_angle(float(step[2]))
        self.mu = self.mu + F_x.T @ step
        self.mu[2] = wrap_angle(float(self.mu[2]))
        if self._invariant:  # ξ's Jacobian is I; the noise is mapped into ξ at the new state
            G, noise = I, noise_map(self.mu)
        R = np.asarray(R, dtype=float)
        self.Sigma = G @ self.Sigma @ G.T + noise @ R @ noise.T
        self._counts["predictions"] += 1

    def update(
        self, landmark_id: int, z: ArrayLike, Q: ArrayLike, t: float | None = None
    ) -> Outcome:
        """Eqs. (12)-(16) with F_x,j (eq. 14) and full-width H."""
        z = np.asarray(z, dtype=float)
        Q = np.asarray(Q, dtype=float)
        j = self.slot.get(landmark_id)
        if j is None and self.sensor.g is None:  # two sightings place it
            return self._triangulate(landmark_id, z, Q)
        if j is None:
            if z[0] * z[0] <= MIN_RANGE_SQUARED:
                return self._count(Outcome.REFUSED)
            j = self._augment(landmark_id, z, Q)
            if self.config.init == "inverse":
                return self._count(Outcome.INITIALISED)
            return self._correct(j, z, Q, gated=False, fresh=True, accepted_as=Outcome.INITIALISED)
        gated = self.config.gate is not None and self._sightings[j] >= self.config.gate_after
        return self._correct(j, z, Q, gated=gated, fresh=False)

    def _augment(self, landmark_id: int, z: np.ndarray, Q: np.ndarray) -> int:
        n = self.n_landmarks
        pose = self.mu[:3]
        m = self.sensor.g(pose, z)
        if self.config.init == "inverse":
            G_p, G_z = self.sensor.G(pose, z)
            if self._invariant:  # ξ_m = ξ_p + G_z δz
                G_p = INVARIANT_NEW_LANDMARK_POSE
            G_x = G_p @ lift_matrix_numeric(n)  # 2 x (2n+3): the new landmark against the state
            top = np.hstack([self.Sigma, self.Sigma @ G_x.T])
            bottom = np.hstack([G_x @ self.Sigma, G_x @ self.Sigma @ G_x.T + G_z @ Q @ G_z.T])
            self.Sigma = np.vstack([top, bottom])
        else:  # eq. (3)
            big = self.config.seed_init_variance * np.eye(2)
            d = self.Sigma.shape[0]
            self.Sigma = np.block([[self.Sigma, np.zeros((d, 2))], [np.zeros((2, d)), big]])
        self.mu = np.concatenate([self.mu, m])
        self._first.append(m.copy())
        self.slot[landmark_id] = n
        self._sightings.append(1)
        self._rejected.append([])
        return n

    def _triangulate(self, landmark_id: int, z: np.ndarray, Q: np.ndarray) -> Outcome:
        """A sensor that needs two sightings (Bailey 2003, `ekfslam.core.initialisation`): the
        first held, its pose cloned into the augmented state (x, c); the landmark placed by a
        later one with enough parallax, through the lifts: G_x = G_b F_x, Σ[L, :] = G_x Σ +
        G_a C_i, Σ[L, L] = G_x Σ G_xᵀ + G_a P_ii G_aᵀ + G_x C_iᵀ G_aᵀ + G_a C_i G_xᵀ + L Q Lᵀ;
        the clone then dropped."""
        ids = list(self._held)
        if landmark_id in ids:
            i = ids.index(landmark_id)
            held = Held(self._c[i].copy(), *self._held[landmark_id])
            later = Held(self.mu[:3].copy(), z, Q)
            placement, keep = triangulated(self.sensor, held, later, self.config.min_parallax)
            if placement is not None:
                return self._place_triangulated(landmark_id, i, placement)
            if keep:
                return self._count(Outcome.DEFERRED)
            self._drop_clone(i)
        ids = list(self._held)
        h, F_x = len(ids), lift_matrix_numeric(self.n_landmarks)
        C_new = F_x @ self.Sigma  # Cov(p, x)
        P = np.zeros((3 * h + 3, 3 * h + 3))
        P[: 3 * h, : 3 * h] = self._P
        P[: 3 * h, 3 * h :] = self._C @ F_x.T  # Cov(c_i, p)
        P[3 * h :, : 3 * h] = P[: 3 * h, 3 * h :].T
        P[3 * h :, 3 * h :] = F_x @ self.Sigma @ F_x.T
        self._c = np.vstack([self._c, self.mu[:3]])
        self._C = np.vstack([self._C.reshape(-1, len(self.mu)), C_new])
        self._P = P
        self._held[landmark_id] = (z, Q)
        return self._count(Outcome.DEFERRED)

    def _place_triangulated(self, landmark_id: int, i: int, placement) -> Outcome:
        n = self.n_landmarks
        G_x = placement.G_b @ lift_matrix_numeric(n)
        G_a = placement.G_a
        C_i, P_ii = self._C[3 * i : 3 * i + 3], self._P[3 * i : 3 * i + 3, 3 * i : 3 * i + 3]
        cross = G_x @ self.Sigma + G_a @ C_i
        own = (
            G_x @ self.Sigma @ G_x.T
            + G_a @ P_ii @ G_a.T
            + G_x @ C_i.T @ G_a.T
            + G_a @ C_i @ G_x.T
            + placement.L @ placement.Q @ placement.L.T
        )
        if too_spread(own, placement.landmark, self.mu[:3], self.config.max_spread):
            return self._count(Outcome.DEFERRED)  # held on, nothing changed
        self.Sigma = np.block([[self.Sigma, cross.T], [cross, own]])
        self._C = np.hstack([self._C, self._C @ G_x.T + self._P[:, 3 * i : 3 * i + 3] @ G_a.T])
        self._drop_clone(i)
        self.mu = np.concatenate([self.mu, placement.landmark])
        self._first.append(placement.landmark.copy())
        self.slot[landmark_id] = n
        self._sightings.append(1)
        self._rejected.append([])
        return self._count(Outcome.INITIALISED)

    def _drop_clone(self, i: int) -> None:
        """Marginalise clone i: its rows out of the augmented state."""
        del self._held[list(self._held)[i]]
        keep = [k for k in range(len(self._c) * 3) if k // 3 != i]
        self._c = np.delete(self._c, i, axis=0)
        self._C, self._P = self._C[keep], self._P[np.ix_(keep, keep)]

    def _reinitialise(self, j: int, z: np.ndarray, Q: np.ndarray) -> Outcome:
        """Slot j from this sighting alone: eq. (12) again, its old rows and columns replaced."""
        n = self.n_landmarks
        pose = self.mu[:3]
        m = self.sensor.g(pose, z)
        rows = slice(3 + 2 * j, 5 + 2 * j)
        if self.config.init == "inverse":
            G_p, G_z = self.sensor.G(pose, z)
            if self._invariant:
                G_p = INVARIANT_NEW_LANDMARK_POSE
            G_x = G_p @ lift_matrix_numeric(n)
            cross = G_x @ self.Sigma
            self.Sigma[rows, :] = cross
            self.Sigma[:, rows] = cross.T
            self.Sigma[rows, rows] = G_x @ self.Sigma @ G_x.T + G_z @ Q @ G_z.T
        else:
            self.Sigma[rows, :] = 0.0
            self.Sigma[:, rows] = 0.0
            self.Sigma[rows, rows] = self.config.seed_init_variance * np.eye(2)
        self.mu[rows] = m
        self._first[j] = m.copy()
        self._sightings[j] = 1
        self._rejected[j] = []
        if self.config.init == "seed":
            return self._correct(
                j, z, Q, gated=False, fresh=True, accepted_as=Outcome.REINITIALISED
            )
        return self._count(Outcome.REINITIALISED)

    def _correct(
        self,
        j: int,
        z: np.ndarray,
        Q: np.ndarray,
        gated: bool,
        fresh: bool,
        accepted_as: Outcome = Outcome.ACCEPTED,
    ) -> Outcome:
        n = self.n_landmarks
        pose = self.mu[:3]
        landmark = self.mu[3 + 2 * j : 5 + 2 * j]
        at_pose, at_landmark = pose, landmark
        if self._fej:  # eq. (14) at the predicted pose and the landmark's first estimate
            at_pose, at_landmark = self._prior, self._first[j]
        for p, m in ((pose, landmark), (at_pose, at_landmark)):
            d = m - p[:2]
            if not float(d @ d) > MIN_RANGE_SQUARED:
                return self._count(Outcome.REFUSED)
        z_hat = self.sensor.h(pose, landmark)
        H_p, H_l = self.sensor.H(at_pose, at_landmark)
        H = np.hstack([H_p, H_l]) @ landmark_lift_matrix_numeric(n, j)  # eq. (14)
        if self._invariant:  # the Jacobian in ξ: H T(μ̂)
            H = H @ error_map(self.mu)
        S = H @ self.Sigma @ H.T + Q
        nu = self.sensor.innovation(z, z_hat)
        if not np.all(np.linalg.eigvalsh(S) > 0):
            return self._count(Outcome.REFUSED)
        nis = float(nu @ np.linalg.solve(S, nu))
        if gated and nis > self.config.gate:
            k = self.config.reinit_after
            if k is not None:  # do the last k sightings, all rejected, agree on a new place?
                k = max(k, self._sightings[j])  # as many as it has accepted, if more
                self._rejected[j] = ([*self._rejected[j], self.sensor.g(pose, z)])[-k:]
                seen = np.array(self._rejected[j])
                centre = seen.mean(axis=0)
                others = [m for i, m in enumerate(self.mu[3:].reshape(-1, 2)) if i != j]
                radius = self.config.reinit_radius
                if (
                    len(seen) == k
                    and np.linalg.norm(seen - centre, axis=1).max() <= radius
                    and all(np.linalg.norm(m - centre) > radius for m in others)
                ):
                    return self._reinitialise(j, z, Q)
            return self._count(Outcome.REJECTED)
        if self.config.iterations > 1:  # Gauss-Newton: H and ν again at the updated estimate
            H, S, nu = self._iterate(j, z, Q, H, S, nu)
        K = self.Sigma @ H.T @ np.linalg.inv(S)  # eq. (15)
        if self._held:  # the clones' rows of the augmented state's gain and update
            K_c = self._C @ H.T @ np.linalg.inv(S)
            self._c = self._c + (K_c @ nu).reshape(-1, 3)
            self._C = self._C - K_c @ H @ self.Sigma
            self._P = self._P - K_c @ S @ K_c.T
        if self._invariant:  # eq. (16) through the group: exp(K ν) X̂
            self.mu = retract(self.mu, K @ nu)
        else:
            self.mu = self.mu + K @ nu  # eq. (16)
        self.mu[2] = wrap_angle(float(self.mu[2]))
        IKH = np.eye(self.Sigma.shape[0]) - K @ H
        self.Sigma = IKH @ self.Sigma @ IKH.T + K @ Q @ K.T
        if not fresh:
            self._sightings[j] += 1
        self._rejected[j] = []
        return self._count(accepted_as)

    def _iterate(self, j, z, Q, H, S, nu):
        """The iterated update's linearisation to commit (`ekfslam.core.filter.iterated`).

        x_i = x̂ + δ_i (or exp(δ_i) X̂), r_i = z - h(x_i) + H_i δ_i, δ_{i+1} = K_i r_i, full
        size; linearisation i >= 1 is taken only if its step lowers the MAP cost
        ½|z - h(x)|²_Q⁻¹ + ½ δᵀ Σ⁻¹ δ. Returns (H, S, r) for eqs. (15)-(16) in place of (H, S, ν).
        """
        n, rows, N = self.n_landmarks, [0, 1, 2, 3 + 2 * j, 4 + 2 * j], self.config.iterations
        taken, candidate, best = (H, S, nu), None, np.inf
        w = np.linalg.solve(S, nu)
        delta, prior = self.Sigma @ H.T @ w, 0.5 * w @ (S - Q) @ w  # δᵀΣ⁻¹δ, δ = Σ Hᵀ w
        for i in range(1, N + 1):
            x = retract(self.mu, delta) if self._invariant else self.mu + delta
            x[2] = wrap_angle(float(x[2]))
            landmark = x[3 + 2 * j : 5 + 2 * j]
            H_p, H_l = self.sensor.H(x[:3], landmark)
            H = np.hstack([H_p, H_l]) @ landmark_lift_matrix_numeric(n, j)
            if self._invariant:
                H = H @ error_map(x)
            S = H @ self.Sigma @ H.T + Q
            residual = self.sensor.innovation(z, self.sensor.h(x[:3], landmark))
            cost = 0.5 * residual @ np.linalg.solve(Q, residual) + prior
            if i >= 2:
                if not cost < best:
                    break
                taken = candidate
            best = cost
            if i == N:
                break
            candidate = (H, S, residual + H @ delta)
            w = np.linalg.solve(S, candidate[2])
            new, prior = self.Sigma @ H.T @ w, 0.5 * w @ (S - Q) @ w
            moved = np.max(np.abs(new - delta)[rows])
            delta = new
            if moved < 1e-7:  # `iterated.TOLERANCE`
                taken = candidate
                break
        return taken

    def _count(self, outcome: Outcome) -> Outcome:
        self._counts[outcome.label] += 1
        return outcome
