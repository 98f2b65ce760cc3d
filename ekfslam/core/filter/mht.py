"""Association with delayed commitment: a bank of JCBB hypotheses (issue 16).

JCBB (`ekfslam.core.filter.associating`) decides each time's pairing for good. When a
sighting of a new landmark falls inside the gate of a poorly known one, or two landmarks stand
close together, that decision is a guess that later sightings would overturn, and a wrong
guess early moves the pose and every decision after it. The classic answer is to keep several
histories and let the evidence choose (Reid, IEEE T-AC 1979; Cox & Leonard, "Modeling a dynamic
environment using a Bayesian multiple hypothesis approach", AI 1994).

`HypothesisBank` keeps at most K = `AssociationConfig.hypotheses` hypotheses, each an
`AssociatingFilter` (EKF mean, Σ and tentatives) with a cumulative log-likelihood score. At each
time with sightings, every hypothesis offers JCBB's pairing and its near alternatives: each
sighting paired with the next compatible landmarks instead (up to `ALTERNATIVES`), or made a
new landmark whatever its NIS (`NEW`). An option scores the Gaussian log-likelihood of its
paired innovations taken jointly, -½(νᵀS⁻¹ν + log det 2πS) with S = H Σ Hᵀ + Q over the pairs
(eq. 13's ν stacked, the cross blocks included), plus `AssociationConfig.new_log_density` for
each sighting no landmark explains. Non-JCBB options must pass JCBB's joint χ² gate. The K best
children over the whole bank are kept, most likely first, each dropped when its state matches a
kept one's within `AssociationConfig.duplicate_radius` (a bank of near-copies remembers
nothing). With K = 1 no alternative is offered, and the bank is ``jcbb`` exactly.

The hypotheses keep no decision lists: each child points to its parent and its option (a
tree), and `finish` walks the winner's chain back. The replay then feeds those options to an
ordinary `AssociatingFilter` with a history (`DecisionReplay`), which reproduces the winner's
state to the last bit, so the history, the scores and the confusion counts are those of every
other method.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.association import UNPAIRED, AssociationConfig, JcbbResult, joint_innovation
from ekfslam.core.filter.associating import AssociatingFilter, AssociationLog, free_nis
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter_checks import check_observe

Array = NDArray[np.float64]

#: An option's entry for a sighting made a new landmark (or left out) whatever its NIS.
NEW = -2
#: How many other compatible landmarks each sighting is offered besides JCBB's choice.
ALTERNATIVES = 2
_LOG_2PI = math.log(2.0 * math.pi)


def log_likelihood(
    pairs: list[tuple[int, int]], nu: Array, P: Array, Q: Array
) -> tuple[float, float]:
    """The joint Gaussian log-likelihood of `pairs` (sighting i, landmark j) and its joint NIS.

    nu (m, n, 2), P (2n, 2n) as `AssociatingFilter._predict_all` gives them, Q (2, 2) each
    sighting's noise. -½(νᵀS⁻¹ν + log det 2πS) over the stacked pairs; (0, 0) for none, and
    (-inf, inf) when S is not positive definite.
    """
    k = len(pairs)
    if k == 0:
        return 0.0, 0.0
    v, S = joint_innovation(pairs, nu, P, np.broadcast_to(Q, (nu.shape[0], 2, 2)))
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return -math.inf, math.inf
    w = np.linalg.solve(L, v)
    d2 = float(w @ w)
    return -0.5 * d2 - float(np.log(np.diag(L)).sum()) - k * _LOG_2PI, d2


def _free_nis(nis: Array, P: Array, Q: Array, option: tuple[int, ...], config) -> list[float]:
    """Each sighting's smallest NIS over the landmarks `option` leaves free as the new-landmark
    rule reads it (`free_nis`; inf for a `NEW` sighting): what decides between ambiguous and new
    (`AssociatingFilter._apply`)."""
    free = free_nis(nis, P, Q, option, config)
    return [math.inf if j == NEW else float(f) for j, f in zip(option, free, strict=True)]


def _same(
    a: AssociatingFilter,
    b: AssociatingFilter,
    radius: float,
    a_mu: Array | None = None,
    b_mu: Array | None = None,
) -> bool:
    """Do two hypotheses hold one state: the same landmarks and tentatives, every mean within
    `radius` (m; rad for the heading)? A sighting made a tentative and one dropped leave the
    same filter state, yet only the first can found a landmark: they are different. a_mu, b_mu:
    their means, when the caller has them (``a.ekf.mu``, ``b.ekf.mu`` otherwise)."""
    a_mu = a.ekf.mu if a_mu is None else a_mu
    b_mu = b.ekf.mu if b_mu is None else b_mu
    if len(a_mu) != len(b_mu) or len(a._tentative) != len(b._tentative):
        return False
    if np.abs(a_mu - b_mu).max() > radius:
        return False
    return all(
        np.abs(p[1] - q[1]).max() <= radius for p, q in zip(a._tentative, b._tentative, strict=True)
    )


def _pairing(option: tuple[int, ...]) -> list[int]:
    """An option as `AssociatingFilter._apply`'s pairing: `NEW` is unpaired there."""
    return [max(j, UNPAIRED) for j in option]


class HypothesisBank:
    """At most `config.hypotheses` `AssociatingFilter`s over one run (see the module).

    Parameters
    ----------
    ekf : the filter every hypothesis starts from (built with record=False: the bank copies it).
    config : AssociationConfig with method "mht".
    """

    def __init__(self, ekf: EKFSLAM, config: AssociationConfig) -> None:
        self.config = config
        # (score, filter, node); node = (parent node, option) or None at the root
        self._bank: list[tuple[float, AssociatingFilter, tuple | None]] = [
            (0.0, AssociatingFilter(ekf, config), None)
        ]

    @property
    def hypotheses(self) -> list[tuple[float, AssociatingFilter]]:
        """(log-likelihood score, filter) of each hypothesis, most likely first."""
        return [(s, af) for s, af, _ in self._bank]

    def predict_many(self, us, dts, ts, M=None, R=None, *, validate: bool = True) -> None:
        """Predict every hypothesis (`EKFSLAM.predict_many`)."""
        for _, af, _ in self._bank:
            af.predict_many(us, dts, ts, M, R, validate=validate)

    def observe(
        self,
        zs: ArrayLike,
        Q: ArrayLike,
        t: float,
        omega: float = 0.0,
        velocity: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """Branch on the sightings taken at time t (s), as `AssociatingFilter.observe`."""
        check_observe(zs, Q, t, "HypothesisBank.observe")  # once: then fed unchecked
        zs = np.asarray(zs, dtype=float).reshape(-1, 2)
        Q, Qs, rate = self._bank[0][1].noises(zs, Q, omega, velocity)
        children = []
        for h, (score, af, _) in enumerate(self._bank):
            for gain, option, free in self._options(af, zs, Q, t, rate):
                children.append((score + gain, h, option, free))
        children.sort(key=lambda c: -c[0])  # stable: ties keep the bank's and options' order
        kept: list[tuple[float, AssociatingFilter, tuple | None]] = []
        means: list[Array] = []  # each kept one's mean (views: a kept child changes no more)
        radius = self.config.duplicate_radius
        for score, h, option, free in children:
            if len(kept) == self.config.hypotheses:
                break
            _, parent, node = self._bank[h]
            child = parent.clone() if self.config.hypotheses > 1 else parent
            child._apply(zs, Qs, t, _pairing(option), free)
            mu = child.ekf.mu
            if any(
                _same(child, k, radius, mu, k_mu)
                for (_, k, _), k_mu in zip(kept, means, strict=True)
            ):
                continue
            kept.append((score, child, (node, option)))
            means.append(mu)
        self._bank = kept

    def _options(self, af: AssociatingFilter, zs: Array, Q: Array, t: float, rate=None):
        """(log-likelihood gain, option, free NIS) of each way this hypothesis can go."""
        if af._tentative:
            af._expire(t)
        m, cfg = len(zs), self.config
        nu, P, nis = af._predict_all(zs, Q, rate)
        found, unclaimed = af._search(nu, P, nis, Q)
        af._counts["nodes"] += found.nodes
        af._counts["budget_hits"] += found.budget_hit
        best = tuple(found.pairing.tolist())
        options = {best: unclaimed.tolist()}
        if cfg.hypotheses > 1:
            for i in range(m):
                others = set(best[:i] + best[i + 1 :])
                same = best[i] == UNPAIRED and unclaimed[i] > cfg.new_landmark  # new already
                alternatives = [] if same else [NEW]
                alternatives += [
                    int(j)
                    for j in np.argsort(nis[i], kind="stable")
                    if nis[i, j] <= cfg.gate and j != best[i] and j not in others
                ][:ALTERNATIVES]
                for j in alternatives:
                    option = (*best[:i], j, *best[i + 1 :])
                    options.setdefault(option, [])
        chi2 = af.joint_gates(m)
        # every option's `log_likelihood` and free NIS in one compiled call (`option_likelihoods`)
        table = np.array(list(options), dtype=np.int64).reshape(len(options), m)
        scores, free_of = np.empty((len(options), 2)), np.empty((len(options), m))
        Qs = np.empty((m, 2, 2))
        Qs[:] = Q
        af.ekf.steps.option_likelihoods((nu, P, nis), Qs, table, scores, free_of)
        out = []
        for b, (option, free) in enumerate(options.items()):
            pairs = sum(j >= 0 for j in option)
            ll, d2 = float(scores[b, 0]), float(scores[b, 1])
            if option != best and pairs and d2 > chi2[pairs]:
                continue
            gain = ll + cfg.new_log_density * (m - pairs)
            if option != best and cfg.new_rule == "threshold":  # `_free_nis`'s, compiled
                smallest = free_of[b].tolist()
                free = [math.inf if j == NEW else f for j, f in zip(option, smallest, strict=True)]
            elif option != best:
                free = _free_nis(nis, P, Q, option, cfg)
            out.append((gain, option, free))
        return out

    def finish(self) -> tuple[float, AssociatingFilter, list[tuple[int, ...]]]:
        """The most likely hypothesis: its score, its filter, and its option for each time."""
        score, af, node = self._bank[0]
        options = []
        while node is not None:
            node, option = node
            options.append(option)
        options.reverse()
        return score, af, options


class DecisionReplay(AssociatingFilter):
    """An `AssociatingFilter` that carries out given options, one per time, instead of choosing.

    Fed the winner's options from `HypothesisBank.finish` over the same schedule, its filter's
    state is the winner's, with a history and a decision log. `nodes` and `budget_hits` are the
    winner's own (this filter searches nothing).
    """

    def __init__(
        self,
        ekf: EKFSLAM,
        config: AssociationConfig,
        winner: AssociatingFilter,
        options: list[tuple[int, ...]],
    ) -> None:
        super().__init__(ekf, config)
        self._options = iter(options)
        self._counts["nodes"] = winner._counts["nodes"]
        self._counts["budget_hits"] = winner._counts["budget_hits"]

    def _jcbb(self, zs: Array, Q: Array, rate=None) -> tuple[JcbbResult, Array]:
        option = next(self._options)
        if len(option) != len(zs):
            raise ValueError(f"an option for {len(option)} sightings given {len(zs)}")
        _, P, nis = self._predict_all(zs, Q, rate)
        free = _free_nis(nis, P, Q, option, self.config)
        pairing = np.array(_pairing(option), dtype=np.int64)
        return JcbbResult(pairing, 0.0, 0, False), np.array(free)

    def finish(self) -> AssociationLog:
        if next(self._options, None) is not None:
            raise ValueError("options left over: the replay is not the bank's schedule")
        return super().finish()
