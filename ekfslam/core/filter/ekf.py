"""The EKF-SLAM filter: the seed's algorithm (eqs. 1-16), touching only the blocks it needs.

State (eq. 1): mu = (x, y, θ, m1x, m1y, ..., mnx, mny), shape (3 + 2n,), and its covariance
Sigma, shape (3 + 2n, 3 + 2n). Landmarks get a slot the first time their id is seen; slot j
occupies indices 3 + 2j and 4 + 2j.

Index ranges, after Solà's toolbox: ``r`` = the pose (0:3), ``l`` = one landmark (3+2j : 5+2j),
``m`` = everything in use (0 : 3+2n). The seed writes the same steps with the lift matrices F_x
(eq. 8) and F_x,j (eq. 14); `ekfslam.teaching.reference` is that literal form, kept as the test
oracle.

Cost per step with n landmarks: prediction O(n) (only the pose rows and columns change), update
O(n^2) (one symmetric rank-2 correction of the used block), landmark initialisation O(n).

The storage, the slots and every view of them (μ, Σ, a landmark, the history) are
`ekfslam.core.filter.state.FilterState`, which this class extends with the steps: storage is
pre-allocated and grows geometrically, and Σ is symmetric, so the steps keep only its lower
triangle current (half the memory traffic of the O(n²) update); `Sigma` fills in the upper one
when it is read.

Speed: the arithmetic of a step lives in `ekfslam.core.filter.kernels`, compiled with numba: as
numpy calls on the seed's small map, per-call overhead cost ten times the arithmetic. This module
keeps the decisions (slots, gating, re-initialisation, counting). `python -m ekfslam bench` measures
it.

With `FilterConfig(linearization="invariant")` (Barrau & Bonnabel 2015) the storage holds the
covariance P of the right-invariant error ξ (`ekfslam.core.invariant`) instead of Σ: the mean is
the same (x, y, θ, m), every covariance handed out is the Cartesian T P Tᵀ to first order
(`FilterState`), and `invariant_covariance` is P itself. Its prediction noise reaches the map
block (O(n²)); the filter owes it and adds it in the next accepted correction's pass, or when Σ
is read (`_settle`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter import iterated, kernels
from ekfslam.core.filter.config import CHI2_2DOF_99 as CHI2_2DOF_99
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.history import OBSERVE, PREDICT, Outcome
from ekfslam.core.filter.state import FilterState
from ekfslam.core.filter_checks import check_predict, check_predict_many, check_update
from ekfslam.core.invariant import INVARIANT_NEW_LANDMARK_POSE
from ekfslam.core.models import (
    MIN_RANGE_SQUARED,
    inverse_observation,
    inverse_observation_jacobians,
)

Array = NDArray[np.float64]


def _rows(values: ArrayLike, width: int | None = None) -> Array:
    """Values as a C-ordered float array, (K,) or (K, width): the kernels' one signature."""
    a = np.ascontiguousarray(values, dtype=float)
    return a if width is None else a.reshape(-1, width)


def _matrix(values: ArrayLike) -> Array:
    a = np.ascontiguousarray(values, dtype=float)
    if a.shape != (3, 3):
        raise ValueError(f"motion noise must be 3x3, got shape {a.shape}")
    return a


_wrap = kernels.wrap
# Inside, outcomes are plain int codes, as the kernels return them, and become `Outcome`s on
# the way out: per observation, `Outcome(code)`, `.label`, `int(outcome)` and even
# `Outcome.ACCEPTED` cost 0.3, 0.15, 0.04 and 0.06 µs, against 2 µs for a whole event.
_OUTCOME = tuple(Outcome)  # the codes are 0, 1, ...: _OUTCOME[code] is Outcome(code)
_LABEL = tuple(o.label for o in Outcome)
_INITIALISED, _ACCEPTED, _REJECTED, _REFUSED, _REINITIALISED = (
    int(Outcome.INITIALISED),
    int(Outcome.ACCEPTED),
    int(Outcome.REJECTED),
    int(Outcome.REFUSED),
    int(Outcome.REINITIALISED),
)


class EKFSLAM(FilterState):
    """Landmark EKF SLAM with a growing state.

    The parameters are `FilterState`'s: the initial pose μ0 of eq. (1), its covariance Σ0 of
    eq. (2) (zero, a known start, by default), the `FilterConfig`, and whether to record a
    `History`.
    """

    def __init__(
        self,
        pose: ArrayLike,
        pose_covariance: ArrayLike | None = None,
        config: FilterConfig | None = None,
        record: bool = True,
    ) -> None:
        super().__init__(pose, pose_covariance, config, record)
        self._sightings: list[int] = []
        self._t = 0.0
        self._fej = self.config.linearization == "fej"
        # FEJ: the robot's predicted position at the current step, and first landmark estimates
        self._prior_xy = (float(self._mu[0]), float(self._mu[1]))
        self._first: list[tuple[float, float]] = []
        self._rejected: list[list[Array]] = []  # per slot: where the rejected sightings put it
        # scratch for the kernels (filled in place: no per-step allocation)
        self._out = np.full(kernels.OUT_SIZE, math.nan)  # ẑ, ν, S, NIS of the last observation
        self._no_rows = np.zeros((1, kernels.ROW_SIZE))  # where nothing is recorded
        self._first_out = np.full(kernels.OUT_SIZE, math.nan)  # iterated: the first ẑ, ν, S, NIS
        self._res = np.zeros(iterated.RES_SIZE)

    def clone(self) -> EKFSLAM:
        """`FilterState.clone`, with the filter's own lists (sightings, FEJ's first estimates)."""
        c = super().clone()
        c._out, c._sightings, c._first = self._out.copy(), list(self._sightings), list(self._first)
        c._rejected = [list(r) for r in self._rejected]
        return c

    # ------------------------------------------------------------- prediction
    def predict(self, u: ArrayLike, R: ArrayLike, t: float | None = None) -> None:
        """Move the pose by the body-frame increment u, eqs. (6), (7) and (9).

        Parameters
        ----------
        u : array (3,)
            (Δux, Δuy, Δθ) in m, m, rad, eq. (4).
        R : array (3, 3)
            Motion noise covariance in the state (x, y, θ) for this step; see
            `ekfslam.core.models.motion_noise` to build it from a control-noise covariance.
        t : float, optional
            Time after the step, s, for the history.

        Only the pose block and the pose-landmark cross blocks change:
        Σ_rr <- G Σ_rr Gᵀ + R and Σ_rm <- G Σ_rm, which is eq. (9) with its lifts done right.
        """
        check_predict(u, R, t)
        self._propagate(
            _rows(u, 3), None, _matrix(R), np.array([self._t if t is None else float(t)])
        )

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
            R_k = V(θ_k) (M dt_k) V(θ_k)ᵀ (`ekfslam.core.models.motion_noise`), θ_k its start
            heading.
        R : (3, 3), or a fixed state-space R for every step (the seed's way). Give M or R.
        """
        check_predict_many(us, dts, ts, M, R)
        if (M is None) == (R is None):
            raise ValueError("give exactly one of M (per second) or R (per step)")
        us = _rows(us, 3)
        dts = _rows(dts) if M is not None else None
        ts = _rows(ts)
        if not len(us) == len(ts) == (len(us) if dts is None else len(dts)):
            raise ValueError(f"{len(us)} increments need as many times (and durations)")
        self._propagate(us, dts, _matrix(M if M is not None else R), ts)

    def _propagate(self, us: Array, dts: Array | None, N: Array, ts: Array) -> None:
        """`ekfslam.core.filter.kernels.propagate`: N is M (per second) when dts is given, else
        R."""
        rec = self._recorder
        if rec is None:
            rows, r0 = self._no_rows, 0
        else:
            r0 = rec.reserve(PREDICT, len(us))
            rows = rec.rows
        use_dts = dts is not None
        if not use_dts:  # ts stands in for dts: the kernel's types are fixed
            dts = ts
        mu, S, d, fej, record = self._mu, self._Sigma, self._dim, self._fej, rec is not None
        px, py, invariant = *self._prior_xy, self._invariant
        # positional, each argument named as the kernel's parameter (tests/core/test_history.py
        # checks it): numba's dispatcher folds keyword arguments at 0.4 µs a call of 14, a
        # quarter of what an event costs
        if self._rho and self._dim != self._owed_to:
            self._settle()  # landmarks came in since: what is owed is owed to fewer rows
        *self._prior_xy, rho = kernels.propagate(
            mu, S, d, us, dts, use_dts, N, fej, invariant, px, py, ts, rows, r0, record
        )
        if invariant:
            self._rho += rho
            self._owed_to = d
        self._counts["predictions"] += len(us)
        if len(ts):
            self._t = float(ts[-1])

    # -------------------------------------------------------------- correction
    def update(
        self, landmark_id: int, z: ArrayLike, Q: ArrayLike, t: float | None = None
    ) -> Outcome:
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
        Outcome
            INITIALISED, ACCEPTED, REJECTED (failed the gate), REINITIALISED (see
            `FilterConfig.reinit_after`), REFUSED (cannot be linearised: the landmark, or
            the observation, sits on the robot) or SINGULAR (the innovation covariance S is
            singular or not finite: the noise is too small or too large). Each is counted
            (`counts`, under its `Outcome.label`).
        """
        check_update(landmark_id, z, Q, t)
        if t is not None:
            self._t = t
        z0, z1 = float(z[0]), float(z[1])
        (q00, q01), (q10, q11) = Qf = np.asarray(Q, dtype=float).tolist()
        if not all(map(math.isfinite, (z0, z1, q00, q01, q10, q11))):
            raise ValueError(f"non-finite observation {z} or noise {Qf} for landmark {landmark_id}")
        z = (z0, z1)
        j = self.slot.get(landmark_id)
        if j is None:
            if z0 * z0 <= MIN_RANGE_SQUARED:
                return self._finish(landmark_id, z, _REFUSED, -1, computed=False)
            j = self._add_landmark(landmark_id, np.array(z), np.asarray(Q, dtype=float))
            if self.config.init == "inverse":
                return self._finish(landmark_id, z, _INITIALISED, 3 + 2 * j, computed=False)
            return self._correct(
                landmark_id, j, z, Qf, gated=False, fresh=True, accepted_as=_INITIALISED
            )
        gated = self.config.gate is not None and self._sightings[j] >= self.config.gate_after
        return self._correct(landmark_id, j, z, Qf, gated=gated, fresh=False)

    def _correct(
        self,
        landmark_id: int,
        j: int,
        z: tuple[float, float],
        Q: list,
        *,
        gated: bool,
        fresh: bool,
        accepted_as: int = _ACCEPTED,
    ) -> Outcome:
        """`ekfslam.core.filter.kernels.correct`, then the bookkeeping of its outcome."""
        mu, S, d, l, work, out = self._mu, self._Sigma, self._dim, 3 + 2 * j, self._work, self._out
        (z0, z1), ((q00, q01), (_, q11)) = z, Q
        gate = self.config.gate if gated else math.inf
        if self._fej:  # Jacobian at p̂(k|k-1) and the landmark's first estimate
            (fx, fy), (px, py) = self._first[j], self._prior_xy
            jx, jy = fx - px, fy - py
        else:
            jx, jy = mu.item(l) - mu.item(0), mu.item(l + 1) - mu.item(1)
        # positional, each argument named as the kernel's parameter (see `_propagate`)
        invariant, rho, dp = self._invariant, self._rho, self._owed_to
        iterations, iterate = self.config.iterations, False
        if iterations > 1:  # the Gauss-Newton linearisation point, as an equivalent z and H
            first, res = self._first_out, self._res
            iterate = iterated.USE == iterated.linearise(
                mu, S, l, z0, z1, q00, q01, q11, invariant, rho, dp, iterations, gate, first, res
            )
            if iterate:
                z0, z1, jx, jy, gate = res[0], res[1], res[2], res[3], math.inf
        outcome = kernels.correct(
            mu, S, d, l, z0, z1, q00, q01, q11, jx, jy, invariant, rho, dp, gate, work, out
        )
        if iterate:  # the history keeps the first linearisation's innovation, S and NIS
            out[:] = self._first_out
        if outcome == _REJECTED and self._should_reinitialise(j, z):
            return self._reinitialise(landmark_id, j, z, Q)
        if outcome == _ACCEPTED:
            self._rho = 0.0  # the correction's pass added it
            outcome = accepted_as
            if not fresh:
                self._sightings[j] += 1
            self._rejected[j].clear()
        return self._finish(landmark_id, z, outcome, l)

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
            if self._invariant:  # ξ_m = ξ_p + G_z δz (`ekfslam.core.invariant`)
                G_p = INVARIANT_NEW_LANDMARK_POSE
            cross = G_p @ S[:d, :3].T  # cov(m_new, everything) = G_p Σ_r,m (lower triangle)
            S[l : l + 2, :d] = cross
            S[:d, l : l + 2] = cross.T
            Sll = cross[:, :3] @ G_p.T + G_z @ Q @ G_z.T
            S[l : l + 2, l : l + 2] = 0.5 * (Sll + Sll.T)
        else:  # eq. (3): nothing known, no correlation
            S[l : l + 2, :d] = 0.0
            S[:d, l : l + 2] = 0.0
            S[l : l + 2, l : l + 2] = self.config.seed_init_variance * np.eye(2)

    def _should_reinitialise(self, j: int, z: tuple[float, float]) -> bool:
        """Have the landmark's last sightings, all rejected, agreed on a new place?

        How many: `reinit_after`, or as many as the sightings it has accepted, if more. A
        landmark placed by one bad sighting is re-placed quickly; one that many sightings
        confirmed is not re-placed by a short run of rejections, which on a long loop means
        the estimate has drifted (re-placing it would throw the loop closure away).
        """
        k = self.config.reinit_after
        if k is None:
            return False
        k = max(k, self._sightings[j])
        seen = self._rejected[j]
        seen.append(inverse_observation(self._mu[:3], z))
        if len(seen) < k:
            return False
        del seen[:-k]
        return _new_place(
            seen, self._mu[3 : self._dim].reshape(-1, 2), j, self.config.reinit_radius
        )

    def _reinitialise(self, landmark_id: int, j: int, z: tuple[float, float], Q: Array) -> Outcome:
        self._settle()
        self._place(j, np.array(z), np.asarray(Q, dtype=float))
        l = 3 + 2 * j
        self._first[j] = (float(self._mu[l]), float(self._mu[l + 1]))
        self._sightings[j] = 1
        self._rejected[j].clear()
        if self.config.init == "seed":  # eq. (3), then the update with this sighting
            return self._correct(
                landmark_id, j, z, Q, gated=False, fresh=True, accepted_as=_REINITIALISED
            )
        return self._finish(landmark_id, z, _REINITIALISED, l, computed=False)

    def _finish(
        self, landmark_id: int, z: tuple[float, float], code: int, l: int, computed=True
    ) -> Outcome:
        """Count the outcome and record the state after it (l < 0: the landmark has no slot).

        code: the `Outcome`'s code (a plain int, as `kernels.correct` returns it).

        computed: whether `kernels.correct` produced this outcome's ẑ, ν, S and NIS (in
        `_out`); otherwise they are recorded as NaN.
        """
        if not computed:
            self._out[:] = math.nan
        self._counts[_LABEL[code]] += 1
        rec = self._recorder
        if rec is not None:
            n = rec.reserve(OBSERVE, 1)
            m = rec.reserve_observation()
            mu, S, t, (z0, z1), out, rows, obs = (
                self._mu,
                self._Sigma,
                self._t,
                z,
                self._out,
                rec.rows,
                rec.obs,
            )
            # positional, each argument named as the kernel's parameter (see `_propagate`)
            invariant, rho, dp = self._invariant, self._rho, self._owed_to
            kernels.record(
                mu, S, l, t, landmark_id, z0, z1, out, code, invariant, rho, dp, rows, n, obs, m
            )
        return _OUTCOME[code]


def _new_place(seen: list, landmarks: Array, j: int, radius: float) -> bool:
    """Do the rejected sightings `seen` (k, 2) agree on one place that no other landmark holds?"""
    seen = np.asarray(seen)
    centre = seen.mean(axis=0)
    if np.max(np.hypot(*(seen - centre).T)) > radius:
        return False
    others = np.delete(landmarks, j, axis=0)
    return not np.any(np.hypot(*(others - centre).T) <= radius)
