"""Data association: which mapped landmark each sighting is, when the sightings carry no id.

Pure numpy over the quantities a filter already has, so each decision can be tested alone:
the innovations ν_ij = z_i - ẑ_j of sighting i against landmark j (bearing wrapped), the joint
covariance P = H Σ Hᵀ of the predicted observations ẑ of the candidate landmarks (one 2x2 block
per landmark, and the cross blocks that a shared pose error puts between them), and each
sighting's noise Q_i. Sighting i and landmark j then have the innovation covariance
S_ij = P_jj + Q_i and the normalised innovation squared NIS_ij = ν_ijᵀ S_ij⁻¹ ν_ij.

Four methods (`AssociationConfig.method`):

- ``known``: the sightings say which landmark they are (AprilTag ids, MRCLAM barcodes); nothing
  here is used, and the filter runs exactly as without this module.
- ``nn``: individual compatibility. Each sighting takes the landmark of smallest NIS when that
  NIS is inside the gate, on its own: two sightings may take the same landmark, and a shared
  pose error that shifts every prediction the same way is not seen (`nearest_neighbour`).
- ``jcbb``: joint compatibility branch and bound (Neira & Tardós, IEEE T-RA 17(6), 2001). Among
  the pairings of all sightings taken at one time, each landmark used at most once and every
  pair individually compatible, take the one with the most pairs whose JOINT NIS (the stacked
  innovation against its full covariance, cross blocks included) is inside the χ² gate of its
  2k degrees of freedom; ties go to the smaller joint NIS (`jcbb`). The search is exponential in
  the worst case, so it stops after `node_budget` nodes with the best pairing found so far, and
  says so.
- ``mht``: JCBB with delayed commitment, a bank of hypotheses (Reid 1979; Cox & Leonard 1994
  for map building): at each time every hypothesis branches on JCBB's pairing and its near
  alternatives, and the `hypotheses` most likely histories are kept
  (`ekfslam.core.filter.mht`). With one hypothesis it is ``jcbb``.

What a sighting that pairs with nothing becomes (`AssociationConfig.new_rule`,
`ekfslam.core.filter.associating.free_nis`): a
new landmark's first sighting (the filter keeps it tentative until it is seen again, see
`ekfslam.core.filter.associating`) when no landmark left free explains it better than a new
landmark would, by their likelihoods (``jcbb``); with ``nn`` and ``mht``, or ``new_rule=
"threshold"``, when its NIS against every landmark left free exceeds the new-landmark threshold.
Otherwise it is ambiguous, and dropped.

`confusion` scores the decisions when the true ids are known after all (our runs, MRCLAM).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.errors import ConfigError

Array = NDArray[np.float64]

METHODS = ("known", "nn", "jcbb", "mht")
UNPAIRED = -1  # a sighting paired with no landmark
NEW_RULES = ("density", "threshold")


@lru_cache(maxsize=256)
def chi2_even_quantile(dof: int, p: float) -> float:
    """The χ² quantile at probability p for an even number of degrees of freedom.

    For dof = 2k the survival function is exp(-x/2) Σ_{i<k} (x/2)^i / i!, a closed form, so
    bisection finds the quantile without scipy (cached: a few dozen (dof, p) pairs ever).
    """
    if dof < 2 or dof % 2:
        raise ValueError(f"dof must be even and >= 2, got {dof}")
    if not 0.0 < p < 1.0:
        raise ValueError(f"p must lie in (0, 1), got {p}")
    k = dof // 2

    def survival(x: float) -> float:
        h, term, total = x / 2.0, 1.0, 1.0
        for i in range(1, k):
            term *= h / i
            total += term
        return math.exp(-h) * total

    lo, hi = 0.0, 2.0 * dof + 100.0
    while survival(hi) > 1.0 - p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if survival(mid) > 1.0 - p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@dataclass(frozen=True)
class AssociationConfig:
    """How sightings without ids are matched to landmarks.

    method : "known" (the sightings' ids; the default), "nn" or "jcbb" (see the module).
    gate : individual compatibility, NIS of one sighting against one landmark (χ²(2) 99%).
    new_landmark : NIS above which, against every landmark, a sighting is a new landmark's
        (χ²(2) at 1 - 1e-5: 23.0) by the "threshold" `new_rule` (and ``nn``'s). Must exceed the
        gate; in between a sighting is ambiguous.
    joint_probability : the joint gate of a k-pair hypothesis is χ²(2k) at this probability.
    node_budget : JCBB search nodes per time step before it returns the best pairing so far.
    tentative_life : s. A tentative landmark not seen again within this time is discarded.
    time_sigma : s, how far a sighting's time stamp may be off the odometry's: the noise it
        adds, in the test and the update, is `ekfslam.core.timestamp`'s. 0 (the default): exact
        (our simulator's); a data source knows its value (`ekfslam.logs.hidden_ids`).
    time_shared : that error is one per image (True), not one per sighting (False, the
        default): ``jcbb`` and ``mht`` test an image's sightings with a shared, cross-correlated
        term (`ekfslam.core.filter.jcbb_kernels.predict_all`) that allows a common shift of
        their bearings but not a relative one.
    hypotheses : ``mht`` only: how many hypotheses the bank keeps (1: ``jcbb`` exactly).
    new_log_density : log of the density, per m·rad of (range, bearing), of a sighting that no
        mapped landmark explains (a new landmark's, or one left out). A pairing scores its
        Gaussian log-likelihood -½(νᵀS⁻¹ν + log det 2πS), so this is the price of explaining
        a sighting otherwise (``mht``'s score; the ``density`` rule of `new_rule`). -5: about
        5% of the density a sighting spread evenly over the camera's 1-7 m by 1.1 rad would
        have (log(1/6.6) = -1.9).
    duplicate_radius : m, ``mht`` only: two hypotheses whose states (pose and every landmark)
        agree within this are one, and the less likely is dropped, so the bank holds different
        maps, not K copies of one that differ in decisions long washed out.
    new_rule : ``jcbb`` and ``mht``: what makes a sighting the search left unpaired a new
        landmark's rather than ambiguous (`ekfslam.core.filter.associating.free_nis`).
        "density": every landmark left free explains it less than `new_log_density` does (a
        likelihood ratio; with MRCLAM's noise a sighting of a mapped landmark is then new above
        NIS ≈ 13-15, of an uncertain one sooner). "threshold": its NIS against each exceeds
        `new_landmark` (``nn`` always decides so). None (the default): "density" for ``jcbb``,
        "threshold" for ``mht``, whose bank already weighs "a new landmark" against each
        pairing by that density (a second density rule would found them twice over).
    """

    method: Literal["known", "nn", "jcbb", "mht"] = "known"
    gate: float = -2.0 * math.log1p(-0.99)
    new_landmark: float = -2.0 * math.log(1e-5)
    joint_probability: float = 0.99
    node_budget: int = 10_000
    tentative_life: float = 10.0
    time_sigma: float = 0.0
    time_shared: bool = False
    hypotheses: int = 8
    new_log_density: float = -5.0
    duplicate_radius: float = 0.05
    new_rule: Literal["density", "threshold"] | None = None

    def __post_init__(self) -> None:
        if self.new_rule is None:  # the method's own (see the class)
            object.__setattr__(self, "new_rule", "threshold" if self.method == "mht" else "density")
        if self.method not in METHODS:
            raise ConfigError(
                f"association must be one of {', '.join(METHODS)}, got {self.method!r}"
            )
        if not 0.0 < self.gate < self.new_landmark < math.inf:
            raise ConfigError(
                f"need 0 < gate < new_landmark < inf, got {self.gate} and {self.new_landmark}"
            )
        if not 0.0 < self.joint_probability < 1.0:
            raise ConfigError(f"joint_probability must lie in (0, 1), got {self.joint_probability}")
        if self.node_budget < 1:
            raise ConfigError(f"node_budget must be at least 1, got {self.node_budget}")
        if not self.tentative_life > 0:
            raise ConfigError(f"tentative_life must be positive, got {self.tentative_life}")
        if not 0.0 <= self.time_sigma < math.inf:
            raise ConfigError(f"time_sigma must be finite and >= 0, got {self.time_sigma}")
        whole = isinstance(self.hypotheses, int) and not isinstance(self.hypotheses, bool)
        if not (whole and self.hypotheses >= 1):
            raise ConfigError(f"hypotheses must be a whole number >= 1, got {self.hypotheses!r}")
        if self.new_rule not in NEW_RULES:
            raise ConfigError(
                f"new_rule must be one of {', '.join(NEW_RULES)}, got {self.new_rule!r}"
            )
        if not math.isfinite(self.new_log_density):
            raise ConfigError(f"new_log_density must be finite, got {self.new_log_density}")
        if not 0.0 <= self.duplicate_radius < math.inf:
            raise ConfigError(
                f"duplicate_radius must be finite and >= 0, got {self.duplicate_radius}"
            )


def individual_nis(nu: ArrayLike, P: ArrayLike, Q: ArrayLike) -> Array:
    """NIS of every sighting against every landmark.

    Parameters
    ----------
    nu : (m, n, 2) innovations z_i - ẑ_j (m, rad; the bearing wrapped).
    P : (2n, 2n) joint covariance H Σ Hᵀ of the n predicted observations.
    Q : (m, 2, 2) noise of each sighting.

    Returns
    -------
    (m, n) ν_ijᵀ (P_jj + Q_i)⁻¹ ν_ij; inf where that S is not positive definite.
    """
    nu, P, Q = (np.asarray(a, dtype=float) for a in (nu, P, Q))
    m, n = nu.shape[:2]
    if n == 0:
        return np.zeros((m, 0))
    blocks = np.stack([P[2 * j : 2 * j + 2, 2 * j : 2 * j + 2] for j in range(n)])  # (n, 2, 2)
    S = blocks[None, :, :, :] + Q[:, None, :, :]  # (m, n, 2, 2)
    a, b, c = S[..., 0, 0], S[..., 0, 1], S[..., 1, 1]
    det = a * c - b * b
    x, y = nu[..., 0], nu[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        nis = (c * x * x - 2.0 * b * x * y + a * y * y) / det
    return np.where((a > 0) & (det > 0) & np.isfinite(nis), nis, math.inf)


def nearest_neighbour(nis: ArrayLike, gate: float) -> Array:
    """Individual compatibility: each sighting's landmark of smallest NIS, if inside the gate.

    nis : (m, n) from `individual_nis`. Returns (m,) landmark indices, `UNPAIRED` (-1) where
    the smallest NIS exceeds the gate. Sightings choose independently (two may choose the same
    landmark): that is the method's weakness JCBB removes.
    """
    nis = np.asarray(nis, dtype=float)
    if nis.shape[1] == 0:
        return np.full(nis.shape[0], UNPAIRED)
    best = np.argmin(nis, axis=1)
    return np.where(nis[np.arange(len(nis)), best] <= gate, best, UNPAIRED)


def joint_innovation(
    pairs: list[tuple[int, int]], nu: Array, P: Array, Q: Array
) -> tuple[Array, Array]:
    """The stacked innovations of `pairs` (sighting i, landmark j), (2k,), and their covariance
    (2k, 2k): P's blocks of the chosen landmarks (cross blocks included: one pose error moves
    every prediction) plus each sighting's Q[i] on the diagonal."""
    k = len(pairs)
    v = np.empty(2 * k)
    S = np.empty((2 * k, 2 * k))
    for a, (i, j) in enumerate(pairs):
        v[2 * a : 2 * a + 2] = nu[i, j]
        for b, (_, jb) in enumerate(pairs):
            S[2 * a : 2 * a + 2, 2 * b : 2 * b + 2] = P[2 * j : 2 * j + 2, 2 * jb : 2 * jb + 2]
        S[2 * a : 2 * a + 2, 2 * a : 2 * a + 2] += Q[i]
    return v, S


def joint_nis(pairs: list[tuple[int, int]], nu: Array, P: Array, Q: Array) -> float:
    """NIS of a hypothesis: νᵀS⁻¹ν over `joint_innovation`; inf when S is not positive definite."""
    if not pairs:
        return 0.0
    v, S = joint_innovation(pairs, nu, P, Q)
    try:
        L = np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return math.inf
    w = np.linalg.solve(L, v)
    return float(w @ w)


@dataclass
class JcbbResult:
    """What `jcbb` chose: pairing (m,) landmark index or -1, its joint NIS, nodes visited, and
    whether the node budget stopped the search (the pairing is then the best found so far)."""

    pairing: Array
    joint_nis: float
    nodes: int
    budget_hit: bool


def jcbb(
    nu: ArrayLike,
    P: ArrayLike,
    Q: ArrayLike,
    gate: float,
    joint_probability: float = 0.99,
    node_budget: int = 10_000,
) -> JcbbResult:
    """Joint compatibility branch and bound (Neira & Tardós 2001) over the sightings of one time.

    Parameters
    ----------
    nu : (m, n, 2), P : (2n, 2n), Q : (m, 2, 2) as in `individual_nis`.
    gate : individual compatibility: only pairs with NIS <= gate are branched on.
    joint_probability : a hypothesis of k pairs is jointly compatible when its joint NIS is
        at most χ²(2k) at this probability.
    node_budget : nodes (hypotheses tried) before the search stops.

    Depth-first over the sightings in order; at sighting i each individually compatible,
    unused landmark is tried in order of increasing NIS, then "no landmark". A branch is cut
    when even pairing every remaining sighting could not beat the best: fewer pairs, or as many
    with a joint NIS already larger (the bound).
    Cost: O(m · n) for the individual test, then up to `node_budget` joint tests of O(k³).
    """
    nu, P, Q = (np.asarray(a, dtype=float) for a in (nu, P, Q))
    m = nu.shape[0]
    nis = individual_nis(nu, P, Q)
    options = [
        [int(j) for j in np.argsort(nis[i], kind="stable") if nis[i, j] <= gate] for i in range(m)
    ]
    best: dict = {"pairs": [], "nis": 0.0}
    state = {"nodes": 0, "hit": False}
    pairs: list[tuple[int, int]] = []
    used: set[int] = set()
    # how many of the sightings from i on could still be paired at all: the bound's slack
    could = [*np.cumsum([bool(o) for o in options][::-1])[::-1].tolist(), 0]

    def better(count: int, value: float) -> bool:
        n_best = len(best["pairs"])
        return count > n_best or (count == n_best and value < best["nis"])

    def hopeful(most: int, value: float) -> bool:
        """Can a branch that pairs at most `most`, its joint NIS already `value`, still win?

        The count bound is Neira & Tardós'; on a tie of counts, adding pairs never lowers a
        joint NIS, so a branch already above the best one's cannot win the tie either.
        """
        n_best = len(best["pairs"])
        return most > n_best or (most == n_best and value < best["nis"])

    def search(i: int, value: float) -> None:
        if i == m:
            if better(len(pairs), value):
                best["pairs"], best["nis"] = list(pairs), value
            return
        if not hopeful(len(pairs) + could[i], value):
            return
        for j in options[i]:
            if j in used:
                continue
            if state["nodes"] >= node_budget:
                state["hit"] = True
                return
            state["nodes"] += 1
            pairs.append((i, j))
            d2 = joint_nis(pairs, nu, P, Q)
            if d2 <= chi2_even_quantile(2 * len(pairs), joint_probability):
                used.add(j)
                search(i + 1, d2)
                used.discard(j)
            pairs.pop()
        if hopeful(len(pairs) + could[i + 1], value):
            search(i + 1, value)  # sighting i paired with nothing

    search(0, 0.0)
    pairing = np.full(m, UNPAIRED)
    for i, j in best["pairs"]:
        pairing[i] = j
    return JcbbResult(pairing, float(best["nis"]), state["nodes"], state["hit"])


# ------------------------------------------------------------------------------ scoring
@dataclass
class Confusion:
    """Decisions against the true ids.

    mapping : {estimated landmark id: true id}, each estimated landmark to the true id most of
        its sightings had. duplicates: estimated landmarks whose true id an earlier one has.
    correct, wrong : sightings paired with a landmark whose mapped true id is / is not theirs.
    missed : sightings left unpaired (ambiguous, or a new tentative) although their true
        landmark was already in the map.
    correct_fraction : correct / (correct + wrong + missed): the founding sightings of landmarks
        not yet mapped are right to be unpaired, so they are not counted.
    """

    mapping: dict[int, int]
    correct: int
    wrong: int
    missed: int
    duplicates: list[int] = field(default_factory=list)

    @property
    def correct_fraction(self) -> float | None:
        total = self.correct + self.wrong + self.missed
        return self.correct / total if total else None


def confusion(estimated: ArrayLike, truth: ArrayLike) -> Confusion:
    """Score per-sighting decisions in time order.

    estimated : (N,) the estimated landmark id each sighting was used for (the sighting that
        made a landmark permanent counts as its first), or `UNPAIRED`.
    truth : (N,) the sightings' true ids.
    """
    est = np.asarray(estimated, dtype=int).tolist()
    true = np.asarray(truth, dtype=int).tolist()
    votes: dict[int, Counter] = {}
    for e, t in zip(est, true, strict=True):
        if e != UNPAIRED:
            votes.setdefault(e, Counter())[t] += 1
    mapping: dict[int, int] = {}
    duplicates: list[int] = []
    claimed: set[int] = set()
    for e in sorted(votes, key=lambda e: -sum(votes[e].values())):  # the most-seen keeps an id
        t = votes[e].most_common(1)[0][0]
        mapping[e] = t
        if t in claimed:
            duplicates.append(e)
        claimed.add(t)
    correct = wrong = missed = 0
    mapped_now: set[int] = set()  # true ids an estimated landmark stood for at that time
    for e, t in zip(est, true, strict=True):
        if e == UNPAIRED:
            missed += t in mapped_now
            continue
        if mapping[e] == t:
            correct += 1
        else:
            wrong += 1
        mapped_now.add(mapping[e])
    return Confusion(mapping, correct, wrong, missed, sorted(duplicates))
