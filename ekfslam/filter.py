"""The EKF-SLAM filter: the seed's algorithm (eqs. 1-16), touching only the blocks it needs.

State (eq. 1): mu = (x, y, θ, m1x, m1y, ..., mnx, mny), shape (3 + 2n,), and its covariance
Sigma, shape (3 + 2n, 3 + 2n). Landmarks get a slot the first time their id is seen; slot j
occupies indices 3 + 2j and 4 + 2j.

Index ranges, after Solà's toolbox: ``r`` = the pose (0:3), ``l`` = one landmark (3+2j : 5+2j),
``m`` = everything in use (0 : 3+2n). The seed writes the same steps with the lift matrices F_x
(eq. 8) and F_x,j (eq. 14); `ekfslam.reference` is that literal form, kept as the test oracle.

Cost per step with n landmarks: prediction O(n) (only the pose rows and columns change), update
O(n^2) (one symmetric rank-2 correction of the used block), landmark initialisation O(n).

Storage is pre-allocated and grows geometrically, so adding a landmark never copies the matrix
(except on the rare doubling of the capacity). The storage beyond the state is kept at zero, so
the hot paths may work on whole (contiguous) rows of it.

Speed: a step costs microseconds, most of it Python's and numpy's per-call overhead; the small
2x2 and 3x3 algebra is therefore written out in plain floats, and the O(n²) covariance update
runs in place in BLAS for larger maps. `python -m ekfslam bench` measures it all.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.covariance import subtract_gram
from ekfslam.filter_config import CHI2_2DOF_99 as CHI2_2DOF_99
from ekfslam.filter_config import FilterConfig, FilterCounts
from ekfslam.history import (
    ACCEPTED,
    INITIALISED,
    OBSERVE,
    OUTCOMES,
    PREDICT,
    REFUSED,
    REINITIALISED,
    REJECTED,
    History,
    Recorder,
)
from ekfslam.models import MIN_RANGE_SQUARED, inverse_observation, inverse_observation_jacobians

Array = NDArray[np.float64]


def _float_rows(values: ArrayLike) -> list:
    """Values as (nested) lists of floats; lists pass through (replay slices its own lists)."""
    return values if isinstance(values, list) else np.asarray(values, dtype=float).tolist()


def _wrap(a: float) -> float:
    a = (a + math.pi) % (2.0 * math.pi) - math.pi
    return -math.pi if a >= math.pi else a


class EKFSLAM:
    """Landmark EKF SLAM with a growing state.

    Parameters
    ----------
    pose : array (3,)
        Initial pose (x, y, θ) in m, m, rad: μ0 of eq. (1).
    pose_covariance : array (3, 3), optional
        Σ0 of eq. (2); zero (a known start, as in the seed) by default.
    config : FilterConfig
    record : bool
        Keep a `History` (default). Turn off for benchmarks of the bare filter.
    """

    def __init__(
        self,
        pose: ArrayLike,
        pose_covariance: ArrayLike | None = None,
        config: FilterConfig | None = None,
        record: bool = True,
    ) -> None:
        self.config = config or FilterConfig()
        cap = 3 + 2 * self.config.initial_capacity
        self._mu = np.zeros(cap)
        self._Sigma = np.zeros((cap, cap))
        self._dim = 3
        self._mu[:3] = np.asarray(pose, dtype=float)
        self._mu[2] = _wrap(float(self._mu[2]))
        if pose_covariance is not None:
            P0 = np.asarray(pose_covariance, dtype=float)
            self._Sigma[:3, :3] = 0.5 * (P0 + P0.T)
        self._ids: list[int] = []
        self.slot: dict[int, int] = {}
        self._sightings: list[int] = []
        self._counts = dict.fromkeys(FilterCounts.__dataclass_fields__, 0)
        self._recorder = Recorder() if record else None
        self._t = 0.0
        self._fej = self.config.linearization == "fej"
        # FEJ: the robot's predicted position at the current step, and first landmark estimates
        self._prior_xy = (float(self._mu[0]), float(self._mu[1]))
        self._first: list[tuple[float, float]] = []
        self._rejected: list[list[Array]] = []  # per slot: where the rejected sightings put it
        # scratch for the small factors of each step (filled in place: no per-step allocation)
        self._g_sum = np.zeros((2, 1))
        self._H_l = np.empty((2, 2))
        self._factors = np.zeros((3, 2))

    # ------------------------------------------------------------------ views
    @property
    def mu(self) -> Array:
        """The state mean (3 + 2n,), eq. (1). A view: do not resize."""
        return self._mu[: self._dim]

    @property
    def Sigma(self) -> Array:
        """The state covariance (3 + 2n, 3 + 2n). A view into pre-allocated storage."""
        return self._Sigma[: self._dim, : self._dim]

    @property
    def pose(self) -> Array:
        """(x, y, θ), a copy."""
        return self._mu[:3].copy()

    @property
    def pose_covariance(self) -> Array:
        """The 3x3 pose block of Sigma, a copy."""
        return self._Sigma[:3, :3].copy()

    @property
    def n_landmarks(self) -> int:
        return len(self._ids)

    @property
    def landmark_ids(self) -> list[int]:
        """Landmark ids in slot order."""
        return list(self._ids)

    @property
    def capacity(self) -> int:
        """How many landmarks fit before the storage doubles."""
        return (self._mu.shape[0] - 3) // 2

    @property
    def counts(self) -> FilterCounts:
        return FilterCounts(**self._counts)

    def landmark(self, landmark_id: int) -> tuple[Array, Array]:
        """Mean (2,) and covariance (2, 2) of one landmark, by id (copies)."""
        l = 3 + 2 * self.slot[landmark_id]
        return self._mu[l : l + 2].copy(), self._Sigma[l : l + 2, l : l + 2].copy()

    def landmark_map(self) -> dict[int, Array]:
        """{landmark id: mean (2,)}, the estimated map."""
        return {i: self._mu[3 + 2 * j : 5 + 2 * j].copy() for j, i in enumerate(self._ids)}

    def history(self) -> History:
        """Everything recorded so far (raises if the filter was built with record=False)."""
        if self._recorder is None:
            raise RuntimeError("this filter was built with record=False")
        return self._recorder.finish()

    # ------------------------------------------------------------- prediction
    def predict(self, u: ArrayLike, R: ArrayLike, t: float | None = None) -> None:
        """Move the pose by the body-frame increment u, eqs. (6), (7) and (9).

        Parameters
        ----------
        u : array (3,)
            (Δux, Δuy, Δθ) in m, m, rad, eq. (4).
        R : array (3, 3)
            Motion noise covariance in the state (x, y, θ) for this step; see
            `ekfslam.models.motion_noise` to build it from a control-noise covariance.
        t : float, optional
            Time after the step, s, for the history.

        Only the pose block and the pose-landmark cross blocks change:
        Σ_rr <- G Σ_rr Gᵀ + R and Σ_rm <- G Σ_rm, which is eq. (9) with its lifts done right.
        """
        R = np.asarray(R, dtype=float)
        self._propagate([(u[0], u[1], u[2])], None, R, [self._t if t is None else t])

    def predict_many(
        self,
        us: ArrayLike,
        dts: ArrayLike,
        ts: ArrayLike,
        M: ArrayLike | None = None,
        R: ArrayLike | None = None,
    ) -> None:
        """Several predictions in a row, exactly as many calls to `predict`, at O(n) once.

        Every motion Jacobian of eq. (7) is I + g e₃ᵀ with g = (g0, g1, 0), so their product is
        I + (Σ g) e₃ᵀ: the pose-landmark cross-covariance needs one update for the whole batch,
        while the 3x3 pose block is stepped in plain floats.

        Parameters
        ----------
        us : (K, 3) increments (Δux, Δuy, Δθ).
        dts : (K,) s, the duration of each step (scales M).
        ts : (K,) s, the time after each step, for the history.
        M : (3, 3), control-increment covariance per second of driving: step k gets
            R_k = V(θ_k) (M dt_k) V(θ_k)ᵀ (`ekfslam.models.motion_noise`), θ_k its start heading.
        R : (3, 3), or a fixed state-space R for every step (the seed's way). Give M or R.
        """
        if (M is None) == (R is None):
            raise ValueError("give exactly one of M (per second) or R (per step)")
        self._propagate(
            _float_rows(us),
            _float_rows(dts) if M is not None else None,
            np.asarray(M if M is not None else R, dtype=float),
            _float_rows(ts),
        )

    def _propagate(self, us: list, dts: list | None, N: Array, ts: list) -> None:
        """Steps in plain floats, eqs. (6), (7) and (9): N is M (per second) when dts is given."""
        x, y, th = self._mu[:3].tolist()
        (s00, s01, s02), (_, s11, s12), (_, _, s22) = self._Sigma[:3, :3].tolist()
        (n00, n01, n02), (_, n11, n12), (_, _, n22) = N.tolist()
        r00, r01, r02, r11, r12, r22 = n00, n01, n02, n11, n12, n22
        A = B = 0.0  # Σ g0 and Σ g1 over the batch
        rows: list[float] = []  # the history's rows of this batch (`ekfslam.history.ROW`)
        record = None if self._recorder is None else rows.extend
        fej = self._fej
        px, py = self._prior_xy  # FEJ: p̂(k|k-1), the first estimate of this step's position
        for k, (dux, duy, dth) in enumerate(us):
            c, s = math.cos(th), math.sin(th)
            dx = dux * c - duy * s  # eq. (6): the step in the world frame
            dy = dux * s + duy * c
            # eq. (7): G = I + g e₃ᵀ with g = (g0, g1, 0) = (-Δy, Δx) of the step
            if fej:  # Δ between the predicted positions, not from the updated one
                g0, g1 = -(y + dy - py), x + dx - px
            else:
                g0, g1 = -dy, dx
            if dts is not None:  # R = V (M dt) Vᵀ with V the rotation of eq. (5)
                dt = dts[k]
                cc, ss, cs = c * c, s * s, c * s
                r00 = (cc * n00 - 2.0 * cs * n01 + ss * n11) * dt
                r01 = (cs * (n00 - n11) + (cc - ss) * n01) * dt
                r11 = (ss * n00 + 2.0 * cs * n01 + cc * n11) * dt
                r02 = (c * n02 - s * n12) * dt
                r12 = (s * n02 + c * n12) * dt
                r22 = n22 * dt
            # eq. (9) on the pose block: G Σ Gᵀ + R, written out for G = I + g e₃ᵀ
            s00, s01, s02, s11, s12, s22 = (
                s00 + 2.0 * g0 * s02 + g0 * g0 * s22 + r00,
                s01 + g0 * s12 + g1 * s02 + g0 * g1 * s22 + r01,
                s02 + g0 * s22 + r02,
                s11 + 2.0 * g1 * s12 + g1 * g1 * s22 + r11,
                s12 + g1 * s22 + r12,
                s22 + r22,
            )
            x += dx
            y += dy
            th += dth
            if not -math.pi <= th < math.pi:
                th = _wrap(th)
            A += g0
            B += g1
            if record is not None:
                record((ts[k], x, y, th, s00, s01, s02, s11, s12, s22))
            px, py = x, y
        if record is not None:
            self._recorder.events(PREDICT, rows)
        mu, S, d = self._mu, self._Sigma, self._dim
        mu[0], mu[1], mu[2] = x, y, th
        self._prior_xy = (px, py)
        if d > 3:
            g = self._g_sum
            g[0, 0], g[1, 0] = A, B
            # Σ_rm <- (Π G) Σ_rm: only the x and y rows change. Whole rows of the storage
            # (their pose block is overwritten below, and they are zero beyond d) are contiguous.
            S[:2] += g * S[2]
            S[3:d, :3] = S[:3, 3:d].T
        S[:3, :3] = ((s00, s01, s02), (s01, s11, s12), (s02, s12, s22))
        self._counts["predictions"] += len(us)
        if ts:
            self._t = ts[-1]

    # -------------------------------------------------------------- correction
    def update(self, landmark_id: int, z: ArrayLike, Q: ArrayLike, t: float | None = None) -> str:
        """Use one range-bearing observation z = (r, φ) of a landmark, eqs. (10)-(16).

        A landmark seen for the first time is added to the state (eq. 12, see `FilterConfig.init`).
        Otherwise the innovation ν = z - ẑ (eq. 13, bearing wrapped) is gated on its NIS, and
        accepted ones update the state with the gain of eq. (15).

        Parameters
        ----------
        landmark_id : int
        z : array (2,)  range (m) and bearing (rad).
        Q : array (2, 2)  observation noise covariance, eq. (11).
        t : float, optional  time of the observation, s.

        Returns
        -------
        str
            "initialised", "accepted", "rejected" (failed the gate), "reinitialised" (see
            `FilterConfig.reinit_after`) or "refused" (cannot be linearised: the landmark, or
            the observation, sits on the robot). Each is counted.
        """
        if t is not None:
            self._t = t
        z = (float(z[0]), float(z[1]))
        Qf = np.asarray(Q, dtype=float).tolist()
        (q00, q01), (q10, q11) = Qf
        if not all(map(math.isfinite, (*z, q00, q01, q10, q11))):
            raise ValueError(f"non-finite observation {z} or noise {Qf} for landmark {landmark_id}")
        j = self.slot.get(landmark_id)
        if j is None:
            if z[0] * z[0] <= MIN_RANGE_SQUARED:
                return self._finish(landmark_id, z, None, None, None, math.nan, REFUSED, None)
            j = self._add_landmark(landmark_id, np.array(z), np.asarray(Q, dtype=float))
            if self.config.init == "inverse":
                l = 3 + 2 * j
                return self._finish(landmark_id, z, None, None, None, math.nan, INITIALISED, l)
            return self._correct(landmark_id, j, z, Qf, False, True, accepted_as=INITIALISED)
        gated = self.config.gate is not None and self._sightings[j] >= self.config.gate_after
        return self._correct(landmark_id, j, z, Qf, gated=gated, fresh=False)

    def _correct(
        self,
        landmark_id: int,
        j: int,
        z: tuple[float, float],
        Q,
        gated: bool,
        fresh: bool,
        accepted_as: int = ACCEPTED,
    ) -> str:
        mu, S, d = self._mu, self._Sigma, self._dim  # storage: zero beyond the state's d
        l = 3 + 2 * j
        x, y, th = mu[:3].tolist()
        mx, my = mu[l : l + 2].tolist()
        dx, dy = mx - x, my - y
        q = dx * dx + dy * dy
        if self._fej:  # Jacobian at p̂(k|k-1) and the landmark's first estimate
            (fx, fy), (px, py) = self._first[j], self._prior_xy
            jx, jy = fx - px, fy - py
        else:
            jx, jy = dx, dy
        jq = jx * jx + jy * jy
        if not (q > MIN_RANGE_SQUARED and jq > MIN_RANGE_SQUARED):
            return self._finish(landmark_id, z, None, None, None, math.nan, REFUSED, l)
        z_hat = (math.sqrt(q), _wrap(math.atan2(dy, dx) - th))
        nu0 = z[0] - z_hat[0]
        nu1 = _wrap(z[1] - z_hat[1])
        # eq. (14) on the rows (x, y, θ, mx, my) is H = [-H_l | -e₂ | H_l] with
        # H_l = [[a, b], [-e, f]]: the observation sees only the landmark relative to the robot.
        # So H Σ = H_l (Σ_l - Σ_xy) - e₂ Σ_θ, from five rows of Σ: O(n), no lift, no n x n work.
        # Whole rows of the storage (zero beyond the state) keep every array contiguous.
        jr = math.sqrt(jq)
        a, b, e, f = jx / jr, jy / jr, jy / jq, jx / jq
        H_l = self._H_l
        H_l[0, 0], H_l[0, 1], H_l[1, 0], H_l[1, 1] = a, b, -e, f
        HS = H_l.dot(S[l : l + 2] - S[:2])  # H Σ, (2, capacity)
        HS[1] -= S[2]
        # S = H Σ Hᵀ + Q (eq. 15's innovation covariance), the same way from H Σ's columns
        (p0x, p0y, p0t), (p1x, p1y, p1t) = HS[:, :3].tolist()
        (p0m, p0n), (p1m, p1n) = HS[:, l : l + 2].tolist()
        s00 = a * (p0m - p0x) + b * (p0n - p0y) + Q[0][0]
        s01 = -e * (p0m - p0x) + f * (p0n - p0y) - p0t + Q[0][1]
        s11 = -e * (p1m - p1x) + f * (p1n - p1y) - p1t + Q[1][1]
        S_innov = (s00, s01, s01, s11)
        # S = L Lᵀ (Cholesky, 2x2); w = L⁻¹ ν makes the NIS νᵀ S⁻¹ ν = |w|²
        det = s00 * s11 - s01 * s01
        if not (s00 > 0.0 and det > 0.0):
            return self._finish(landmark_id, z, z_hat, (nu0, nu1), S_innov, math.nan, REFUSED, l)
        l00 = math.sqrt(s00)
        l10 = s01 / l00
        l11 = math.sqrt(det) / l00  # = √(s11 - l10²)
        w0 = nu0 / l00
        w1 = (nu1 - l10 * w0) / l11
        nis = w0 * w0 + w1 * w1
        if gated and nis > self.config.gate:
            if self._should_reinitialise(j, z):
                return self._reinitialise(landmark_id, j, z, Q)
            return self._finish(landmark_id, z, z_hat, (nu0, nu1), S_innov, nis, REJECTED, l)
        # eq. (15)-(16) with W = L⁻¹ H Σ: K = Σ Hᵀ S⁻¹ = Wᵀ L⁻¹, so K S Kᵀ = Wᵀ W and Σ -= Wᵀ W,
        # which for the optimal gain equals Joseph's form (I-KH)Σ(I-KH)ᵀ + KQKᵀ and keeps Σ
        # symmetric. One product gives W and (K ν)ᵀ = (S⁻¹ ν)ᵀ H Σ = (L⁻ᵀ w)ᵀ H Σ together.
        F = self._factors  # rows: L⁻¹ (2x2), then (L⁻ᵀ w)ᵀ
        F[0, 0], F[1, 0], F[1, 1] = 1.0 / l00, -l10 / (l00 * l11), 1.0 / l11
        F[2, 1] = w1 / l11
        F[2, 0] = (w0 - l10 * F[2, 1]) / l00
        Y = F.dot(HS)  # (3, capacity): W, then (K ν)ᵀ
        mu += Y[2]
        th = mu.item(2)
        if not -math.pi <= th < math.pi:
            mu[2] = _wrap(th)
        subtract_gram(S, Y[:2], d)
        if not fresh:
            self._sightings[j] += 1
        self._rejected[j].clear()
        return self._finish(landmark_id, z, z_hat, (nu0, nu1), S_innov, nis, accepted_as, l)

    def _add_landmark(self, landmark_id: int, z: Array, Q: Array) -> int:
        """Append a landmark slot, eq. (12) for the mean; covariance by `config.init`."""
        j = len(self._ids)
        if self._dim + 2 > self._mu.shape[0]:
            self._grow()
        self._dim += 2
        self._place(j, z, Q)
        self._ids.append(landmark_id)
        self.slot[landmark_id] = j
        self._sightings.append(1)
        self._first.append((float(self._mu[3 + 2 * j]), float(self._mu[4 + 2 * j])))
        self._rejected.append([])
        return j

    def _place(self, j: int, z: Array, Q: Array) -> None:
        """Set slot j from one sighting as if first seen now, dropping what it held."""
        mu, S, d = self._mu, self._Sigma, self._dim
        l = 3 + 2 * j
        pose = mu[:3]
        mu[l : l + 2] = inverse_observation(pose, z)
        if self.config.init == "inverse":
            G_p, G_z = inverse_observation_jacobians(pose, z)
            cross = G_p @ S[:3, :d]  # cov(m_new, everything) = G_p Σ_r,m
            S[l : l + 2, :d] = cross
            S[:d, l : l + 2] = cross.T
            Sll = cross[:, :3] @ G_p.T + G_z @ Q @ G_z.T
            S[l : l + 2, l : l + 2] = 0.5 * (Sll + Sll.T)
        else:  # eq. (3): nothing known, no correlation
            S[l : l + 2, :d] = 0.0
            S[:d, l : l + 2] = 0.0
            S[l : l + 2, l : l + 2] = self.config.seed_init_variance * np.eye(2)

    def _should_reinitialise(self, j: int, z: tuple[float, float]) -> bool:
        """Do the landmark's last `reinit_after` sightings, all rejected, agree with each other?"""
        k = self.config.reinit_after
        if k is None:
            return False
        seen = self._rejected[j]
        seen.append(inverse_observation(self._mu[:3], z))
        if len(seen) < k:
            return False
        del seen[:-k]
        return _new_place(
            seen, self._mu[3 : self._dim].reshape(-1, 2), j, self.config.reinit_radius
        )

    def _reinitialise(self, landmark_id: int, j: int, z: tuple[float, float], Q: Array) -> str:
        self._place(j, np.array(z), np.asarray(Q, dtype=float))
        l = 3 + 2 * j
        self._first[j] = (float(self._mu[l]), float(self._mu[l + 1]))
        self._sightings[j] = 1
        self._rejected[j].clear()
        if self.config.init == "seed":  # eq. (3), then the update with this sighting
            return self._correct(landmark_id, j, z, Q, False, True, accepted_as=REINITIALISED)
        return self._finish(landmark_id, z, None, None, None, math.nan, REINITIALISED, l)

    def _grow(self) -> None:
        d = self._dim
        cap = 3 + 2 * (2 * self.capacity)
        mu = np.zeros(cap)
        S = np.zeros((cap, cap))
        mu[:d] = self._mu[:d]
        S[:d, :d] = self._Sigma[:d, :d]
        self._mu, self._Sigma = mu, S

    def _finish(
        self,
        landmark_id: int,
        z: tuple[float, float],
        z_hat: tuple[float, float] | None,
        nu: tuple[float, float] | None,
        S_innov: tuple[float, ...] | None,
        nis: float,
        outcome: int,
        l: int | None,
    ) -> str:
        name = OUTCOMES[outcome]
        self._counts[name] += 1
        rec = self._recorder
        if rec is not None:
            mu, S = self._mu, self._Sigma
            if l is None:
                lm, lc = (math.nan, math.nan), ((math.nan, math.nan), (math.nan, math.nan))
            else:
                lm, lc = mu[l : l + 2].tolist(), S[l : l + 2, l : l + 2].tolist()
            (s00, s01, s02), (_, s11, s12), (_, _, s22) = S[:3, :3].tolist()
            rec.event(OBSERVE, (self._t, *mu[:3].tolist(), s00, s01, s02, s11, s12, s22))
            rec.observation(self._t, landmark_id, z, z_hat, nu, S_innov, nis, outcome, lm, lc)
        return name


def _new_place(seen: list, landmarks: Array, j: int, radius: float) -> bool:
    """Do the rejected sightings `seen` (k, 2) agree on one place that no other landmark holds?"""
    seen = np.asarray(seen)
    centre = seen.mean(axis=0)
    if np.max(np.hypot(*(seen - centre).T)) > radius:
        return False
    others = np.delete(landmarks, j, axis=0)
    return not np.any(np.hypot(*(others - centre).T) <= radius)
