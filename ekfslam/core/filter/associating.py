"""The filter's correction when sightings carry no id: associate, then update (issue 16).

`AssociatingFilter` wraps an `ekfslam.core.filter.ekf.EKFSLAM`. For the sightings taken at one
time the filter predicts every mapped landmark's observation and the joint covariance of those
predictions (`EKFSLAM.predictions`, `EKFSLAM.nearest`: `ekfslam.core.filter.predictions`), the
pairing is chosen (``nn`` or ``jcbb``, deciding as `ekfslam.core.association`'s readable forms),
and each paired sighting is fed to `EKFSLAM.update` under the landmark's estimated id (0, 1, 2
... in the order they become permanent), one after the other as the replay does with known ids.
``nn`` needs only each landmark's own 2x2 block of that covariance (O(m n)) and costs about what
the updates do; ``jcbb`` needs the cross blocks too, and its branch and bound
(`ekfslam.core.filter.jcbb_search`) decides as `ekfslam.core.association.jcbb` over
`predicted`, the readable form; both run as the filter's steps do, compiled or not. The EKF
itself is unchanged: its gate and re-initialisation still apply to each update.

Two sightings of one time never come from one landmark (the assumption JCBB's pairing makes): a
sighting JCBB left unpaired is judged ambiguous only against the landmarks no other sighting of its
time took (`AssociatingFilter._jcbb`). A time stamp that may be off by
`AssociationConfig.time_sigma` makes a sighting taken while turning uncertain in bearing, and its Q
says so. With `AssociationConfig.time_shared` that error is one per image: all its sightings were
taken from the pose at t + δt, off by u δt (u the pose's rate, eq. 6), so ``jcbb``'s joint test (and
``mht``'s likelihood) carry the cross-correlated term σt² g gᵀ, g_j = H_pose,j u (eq. 14): a common
shift of the image's bearings passes, a relative one does not
(`ekfslam.core.filter.predictions.predict_all`). The updates still run one sighting at a time
through `EKFSLAM.update`, each with its own share σt² g gᵀ of that term (`shared_sighting_noise`):
an exact joint update would need δt in the state for the image's updates. Measured on MRCLAM Dataset
7, updating with the independent (ω σt)² instead moves the maps by at most 0.04x known.

A sighting paired with nothing:

- ambiguous (a landmark left free explains it about as well as a new one would,
  `free_nis`; with ``nn``: its smallest NIS lies between the gate and
  the new-landmark threshold): dropped, counted;
- otherwise a new landmark, which starts TENTATIVE, outside the state, as the position the
  sighting puts it at. The rule: a tentative becomes a landmark when a later sighting (at a
  later time) that pairs with no mapped landmark puts it within the gate of the tentative
  (Mahalanobis, over both sightings' noise and the pose uncertainty added between them: the
  pose error they share cancels, see `AssociatingFilter._new_sighting`); the filter
  is then initialised from that second sighting. A tentative not confirmed within
  `AssociationConfig.tentative_life` seconds is discarded and counted, so a single spurious
  sighting never becomes a landmark.

Linearisation: the predictions use the current estimate, also under FEJ (the association is a
test, not an update; FEJ's Jacobians still apply to the updates themselves).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.association import (
    UNPAIRED,
    AssociationConfig,
    JcbbResult,
    chi2_even_quantile,
)
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter.jcbb_search import Limits
from ekfslam.core.filter.predictions import Predicted, Rate
from ekfslam.core.filter_checks import check_observe
from ekfslam.core.timestamp import TimeError, image_noises, time_shift

Array = NDArray[np.float64]

#: What became of each sighting (`AssociationLog.decision`).
ASSOCIATED, CONFIRMED, TENTATIVE, AMBIGUOUS = "associated", "confirmed", "tentative", "ambiguous"


@dataclass(frozen=True)
class AssociationCounts:
    """Every sighting is counted once: associated + confirmed + tentative + ambiguous = all.

    associated : paired with a mapped landmark (then updated; the EKF's gate may still reject).
    confirmed : made a tentative landmark permanent (``new`` landmarks).
    tentative : started a tentative landmark. tentative_discarded : tentatives never confirmed.
    ambiguous : inside no landmark's gate but not far enough from all to be new: dropped.
    budget_hits, nodes : JCBB steps that ran out of their node budget; nodes searched in all.
    """

    associated: int
    confirmed: int
    tentative: int
    tentative_discarded: int
    ambiguous: int
    budget_hits: int
    nodes: int


@dataclass(frozen=True)
class AssociationLog:
    """The decisions of a run, one entry per sighting in the order they were fed.

    method : the `AssociationConfig.method`. estimated : (N,) the estimated landmark id each
    sighting was used for, -1 (`UNPAIRED`) when none. decision : (N,) one of ASSOCIATED,
    CONFIRMED, TENTATIVE, AMBIGUOUS. counts : `AssociationCounts`.
    """

    method: str
    estimated: NDArray[np.int64]
    decision: tuple[str, ...]
    counts: AssociationCounts


def shares_image_error(config: AssociationConfig) -> bool:
    """Whether `config` treats a time-stamp error as one per image: ``time_shared``, except for
    ``nn``, which tests one sighting at a time (the independent term)."""
    return config.time_shared and config.method != "nn"


def free_nis(
    nis: ArrayLike, P: ArrayLike, Q: ArrayLike, pairing: ArrayLike, config: AssociationConfig
) -> Array:
    """Each sighting's smallest NIS over the landmarks `pairing` leaves free (inf: none), as the
    new-landmark test reads it: above `config.new_landmark` a sighting left unpaired is new.

    nis : (m, n) `individual_nis`; P : (2n, 2n) H Σ Hᵀ; Q : (2, 2) the sightings' noise;
    pairing : (m,) landmark index or a negative value (unpaired). With the "density"
    `AssociationConfig.new_rule` a sighting is new (inf) when every free landmark's likelihood
    -½(NIS + log det 2πS), S = P_jj + Q (the bracket of eq. (15); ν from eq. (13)), falls below
    `config.new_log_density`, and ambiguous (at most `new_landmark`) otherwise.
    """
    nis, P, Q = (np.asarray(a, dtype=float) for a in (nis, P, Q))
    m, n = nis.shape
    free = np.ones(n, dtype=bool)
    free[[j for j in np.asarray(pairing).tolist() if j >= 0]] = False
    if not free.any():
        return np.full(m, np.inf)
    smallest = nis[:, free].min(axis=1)
    if config.new_rule == "threshold":
        return smallest
    idx = np.flatnonzero(free)
    S = np.stack([P[2 * j : 2 * j + 2, 2 * j : 2 * j + 2] for j in idx]) + Q
    logdet = np.log(np.linalg.det(2.0 * math.pi * S))
    best = (-0.5 * (nis[:, free] + logdet[None, :])).max(axis=1)
    ambiguous = np.minimum(smallest, config.new_landmark)
    return np.where(best < config.new_log_density, np.inf, ambiguous)


class AssociatingFilter:
    """An EKF whose sightings are matched to landmarks by `config.method` ("nn" or "jcbb"; with
    "mht" each hypothesis of `ekfslam.core.filter.mht.HypothesisBank` is one, deciding as "jcbb").

    Parameters
    ----------
    ekf : the filter to correct (its landmark ids become the estimated ids 0, 1, ...).
    config : AssociationConfig; its method must not be "known" (that needs no association).
    """

    def __init__(self, ekf: EKFSLAM, config: AssociationConfig) -> None:
        if config.method == "known":
            raise ValueError("'known' association feeds EKFSLAM.update directly")
        self.ekf = ekf
        self.config = config
        self._tentative: list[tuple[float, Array, Array, Array]] = []  # t, p, cov, pose cov
        self._estimated: list[int] = []
        self._decision: list[str] = []
        self._chi2: dict[int, Array] = {}  # m -> the joint gates of 0..m pairs
        self._counts = dict.fromkeys(
            (
                "associated",
                "confirmed",
                "tentative",
                "tentative_discarded",
                "ambiguous",
                "budget_hits",
                "nodes",
            ),
            0,
        )

    def clone(self) -> AssociatingFilter:
        """An independent copy (filter state, tentatives, counts) whose decision log starts
        empty: one hypothesis of `ekfslam.core.filter.mht`, which keeps the decisions itself."""
        c = copy.copy(self)
        c.ekf = self.ekf.clone()
        c._tentative, c._counts = list(self._tentative), dict(self._counts)
        c._estimated, c._decision = [], []
        return c

    def predict_many(self, us, dts, ts, M=None, R=None, *, validate: bool = True) -> None:
        """`EKFSLAM.predict_many` of the filter (the replay's call, as for `HypothesisBank`)."""
        self.ekf.predict_many(us, dts, ts, M, R, validate=validate)

    def noises(
        self, zs: Array, Q: ArrayLike, omega: float, velocity: tuple[float, float]
    ) -> tuple[Array, Array, tuple[float, float, float] | None]:
        """The test's Q (2, 2), the updates' (2, 2) or (m, 2, 2), and the rate the joint test
        shares among the image's sightings (None: none) for sightings taken at body velocity
        (m/s) and turn rate omega (rad/s), after `AssociationConfig.time_sigma` and
        ``time_shared`` (``nn`` tests one sighting at a time: the independent term)."""
        cfg, rate = self.config, (velocity[0], velocity[1], omega)
        error = TimeError(cfg.time_sigma, shares_image_error(cfg))
        return image_noises(Q, zs, rate, error, self.ekf.sensor)

    def observe(
        self,
        zs: ArrayLike,
        Q: ArrayLike,
        t: float,
        omega: float = 0.0,
        velocity: tuple[float, float] = (0.0, 0.0),
    ) -> list[int]:
        """Use the sightings taken at time t (s): zs (m, 2) range (m), bearing (rad); Q (2, 2).

        omega : rad/s, the robot's turn rate at t; with `AssociationConfig.time_sigma` it adds
        (omega time_sigma)² to the bearing variance of these sightings (a time-stamp error).
        velocity : m/s, the robot's body velocity (vx, vy) at t; used with
        `AssociationConfig.time_shared`, where the image's one time-stamp error moves the pose
        of all its sightings together (`noises`).
        Returns the estimated landmark id each sighting was used for (-1: none).
        """
        check_observe(zs, Q, t, "AssociatingFilter.observe")  # once: then fed unchecked
        zs = np.asarray(zs, dtype=float).reshape(-1, 2)
        Q, Qs, rate = self.noises(zs, Q, omega, velocity)
        if self._tentative:
            self._expire(t)
        if self.config.method == "nn":  # compiled, O(m n): no H Σ Hᵀ (see `nearest.nearest`)
            pairing, nearest = self._nearest(zs, Q)
        else:
            found, unclaimed = self._jcbb(zs, Q, rate)
            pairing, nearest = found.pairing.tolist(), unclaimed.tolist()
            self._counts["nodes"] += found.nodes
            self._counts["budget_hits"] += found.budget_hit
        return self._apply(zs, Qs, t, pairing, nearest)

    def _apply(
        self, zs: Array, Q: Array, t: float, pairing: list[int], nearest: list[float]
    ) -> list[int]:
        """Carry out a pairing (m,) of the sightings zs with landmark slots (-1: none): update,
        then decide each unpaired one by its smallest NIS over the landmarks left free,
        `nearest` (m,); record and count. Q: (2, 2), or (m, 2, 2) one per sighting. Returns the
        estimated id each sighting was used for."""
        m, ids = len(zs), self.ekf.landmark_ids
        Q = Q if Q.ndim == 3 else (Q,) * m  # each sighting's
        used = [UNPAIRED] * m
        decision = [ASSOCIATED] * m
        for i in range(m):  # the paired ones first: each update sharpens the pose
            if pairing[i] != UNPAIRED:
                used[i] = ids[pairing[i]]
                self.ekf.update(used[i], zs[i], Q[i], t, validate=False)
        for i in range(m):
            if pairing[i] != UNPAIRED:
                continue
            if nearest[i] <= self.config.new_landmark:
                decision[i] = AMBIGUOUS
            else:
                used[i], decision[i] = self._new_sighting(zs[i], Q[i], t)
        for e, what in zip(used, decision, strict=True):  # in the sightings' order, for scoring
            self._estimated.append(e)
            self._decision.append(what)
            self._counts[what] += 1
        return used

    def decide(
        self,
        zs: ArrayLike,
        Q: ArrayLike,
        omega: float = 0.0,
        velocity: tuple[float, float] = (0.0, 0.0),
    ) -> list[int]:
        """The landmark ids `observe` would pair the sightings with now (-1: none), changing
        nothing: to ask how well the association does from a given state (the one the filter
        reaches with the true ids, say)."""
        zs = np.asarray(zs, dtype=float).reshape(-1, 2)
        Q, _, rate = self.noises(zs, Q, omega, velocity)
        if self.config.method == "nn":
            pairing = self._nearest(zs, Q)[0]
        else:
            pairing = self._jcbb(zs, Q, rate)[0].pairing.tolist()
        ids = self.ekf.landmark_ids
        return [UNPAIRED if j == UNPAIRED else ids[j] for j in pairing]

    def _nearest(self, zs: Array, Q: Array) -> tuple[list[int], list[float]]:
        """`nearest_neighbour` over `individual_nis`, by the filter: pairing and smallest NIS."""
        return self.ekf.nearest(zs, Q, self.config.gate)

    def _jcbb(self, zs: Array, Q: Array, rate=None) -> tuple[JcbbResult, Array]:
        """`jcbb` over `predicted` and `individual_nis`, compiled (`jcbb_kernels`): the same
        decision; and each sighting's smallest NIS over the landmarks no sighting took (m,).

        One landmark gives at most one sighting per time (JCBB's own hypothesis), so a sighting
        left unpaired is ambiguous only against landmarks no other sighting of its time took:
        else the second tag of a close pair, seen with the first, would be ambiguous against
        the first for ever, and never mapped.
        """
        return self._search(*self._predict_all(zs, Q, rate), Q)

    def _predict_all(self, zs: Array, Q: Array, rate=None) -> Predicted:
        """ν (m, n, 2), P = H Σ Hᵀ (2n, 2n) and the individual NIS (m, n), by the filter; with a
        rate (vx, vy, ω) from `noises`, P holds the image's shared time-stamp term too."""
        shared = None
        if rate is not None:
            vx, vy, w = rate
            shared = Rate(np.array([vx, vy]), float(w), self.config.time_sigma**2)
        return self.ekf.predictions(zs, Q, shared)

    def joint_gates(self, m: int) -> Array:
        """χ²(2k) at the joint probability for k = 0..m pairs (index 0 unused), cached."""
        if m not in self._chi2:
            p = self.config.joint_probability
            gates = [chi2_even_quantile(2 * k, p) for k in range(1, m + 1)]
            self._chi2[m] = np.array([0.0, *gates])
        return self._chi2[m]

    def _search(self, nu: Array, P: Array, nis: Array, Q: Array) -> tuple[JcbbResult, Array]:
        """JCBB's branch and bound over `_predict_all`'s arrays (see `_jcbb`)."""
        m = len(nis)
        limits = Limits(self.config.gate, self.joint_gates(m), self.config.node_budget)
        Qs = np.empty((m, 2, 2))  # each sighting's noise: the search takes a stack
        Qs[:] = Q
        pairing, unclaimed = np.empty(m, dtype=np.int64), np.empty(m)
        value, nodes, hit = self.ekf.steps.search(
            (nu, P, nis), Qs, tuple(limits), pairing, unclaimed
        )
        if self.config.new_rule != "threshold":  # the search's figure is the threshold's
            unclaimed = free_nis(nis, P, Q, pairing, self.config)
        return JcbbResult(pairing, value, nodes, hit), unclaimed

    def predicted(self, zs: Array, rate=None) -> tuple[Array, Array]:
        """Innovations ν (m, n, 2) of every sighting against every landmark, and P = H Σ Hᵀ,
        written out with the whole H (2n, d): the readable form `_predict_all` is tested
        against. With a body rate (vx, vy, ω), plus the image's shared time-stamp term
        time_sigma² g gᵀ, g_j = H_pose,j u (`ekfslam.core.timestamp.time_shift`)."""
        ekf, sensor = self.ekf, self.ekf.sensor
        mu, n = ekf.mu, ekf.n_landmarks
        pose, d = mu[:3], 3 + 2 * n
        nu = np.zeros((len(zs), n, 2))
        H = np.zeros((2 * n, d))  # eq. (14) for each landmark, stacked
        g = np.zeros(2 * n)
        for j in range(n):
            landmark = mu[3 + 2 * j : 5 + 2 * j]
            z_hat = sensor.h(pose, landmark)
            for i, z in enumerate(zs):
                nu[i, j] = sensor.innovation(z, z_hat)
            H_r, H_l = sensor.H(pose, landmark)
            H[2 * j : 2 * j + 2, :3], H[2 * j : 2 * j + 2, 3 + 2 * j : 5 + 2 * j] = H_r, H_l
            if rate is not None:
                g[2 * j : 2 * j + 2] = time_shift(z_hat, rate, sensor)
        P = H @ ekf.Sigma @ H.T
        if rate is not None and n:
            P = P + self.config.time_sigma**2 * np.outer(g, g)
        return nu, P

    def _new_sighting(self, z: Array, Q: Array, t: float) -> tuple[int, str]:
        """A sighting of no mapped landmark: confirm a tentative one, or start one.

        The two sightings share the pose error of the earlier one (the robot's drift is the
        same for both), so the test's covariance is each sighting's own noise, G_z Q G_zᵀ, plus
        the pose uncertainty added in between (the part of Σ_rr(t) - Σ_rr(t0) that grew),
        through G_p: with the whole pose covariance twice, a drifted robot would confirm one
        landmark with its neighbour's sighting.
        """
        pose, sensor = self.ekf.mu[:3], self.ekf.sensor
        G_p, G_z = sensor.G(pose, z)
        p = sensor.g(pose, z)
        C = G_z @ Q @ G_z.T
        P_now = self.ekf.pose_covariance
        for k, (t0, p0, C0, P0) in enumerate(self._tentative):
            if t0 >= t:
                continue  # seen again means at a later time
            w, V = np.linalg.eigh(P_now - P0)
            grown = (V * np.maximum(w, 0.0)) @ V.T
            v = p - p0
            S = C + C0 + G_p @ grown @ G_p.T
            if v @ np.linalg.solve(S, v) <= self.config.gate:
                del self._tentative[k]
                new_id = self.ekf.n_landmarks
                self.ekf.update(new_id, z, Q, t, validate=False)
                return new_id, CONFIRMED
        self._tentative.append((t, p, C, P_now))
        return UNPAIRED, TENTATIVE

    def _expire(self, t: float) -> None:
        life = self.config.tentative_life
        keep = [e for e in self._tentative if t - e[0] <= life]
        self._counts["tentative_discarded"] += len(self._tentative) - len(keep)
        self._tentative = keep

    def finish(self) -> AssociationLog:
        """The decisions so far; the tentatives still waiting count as discarded."""
        counts = dict(self._counts)
        counts["tentative_discarded"] += len(self._tentative)
        return AssociationLog(
            method=self.config.method,
            estimated=np.array(self._estimated, dtype=np.int64),
            decision=tuple(self._decision),
            counts=AssociationCounts(**counts),
        )
