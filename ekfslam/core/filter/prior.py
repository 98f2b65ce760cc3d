"""A map known before the run starts: decide again with a first pass's map (issue 16).

A filter that decides the association while it maps decides each early sighting from a map and a
pose that are still poor, and a wrong decision then moves both. The classic remedy is to
alternate (hard EM over the correspondences): decide the whole run once, take the map it ends
with, and decide every sighting again from the start with that map known in advance
(`ekfslam.pipeline.replay`'s ``passes``). It is offline: the run is read once per pass.

`PriorMap` is what one pass hands the next: the landmark means (eq. 1's m) and their joint
covariance, the map block Σ_mm of the final Σ (eq. 2's layout). Both passes start at the same
pose with the same Σ0, so the final map is already expressed in the frame the next pass starts
in; its correlation with the *final* pose is dropped (the next pass's pose starts at the start,
not where the last one ended), and nothing else is changed. Measured on MRCLAM Dataset 7: the map
block as it is decides best; inflated 2 or 4 times it lets robot 1 get lost (README).

`start_with` puts such a map into a fresh filter before its first step: slot j holds landmark j
(the estimated ids of the pass that made the map), with no correlation to the start pose, whose
Σ0 is the filter's own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter.history import History, Outcome

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class PriorMap:
    """A map to start from.

    means : (n, 2) m, landmark j's position in the frame the filter starts in.
    covariance : (2n, 2n) m², their joint covariance (landmark j at rows 2j, 2j + 1).
    sightings : (n,) the sightings each landmark had when the map was made (the filter's
        re-initialisation rule weighs a landmark's rejections by them, `FilterConfig.reinit_after`).
    """

    means: Array
    covariance: Array
    sightings: tuple[int, ...]

    def __post_init__(self) -> None:
        n = len(self.means)
        if np.shape(self.means) != (n, 2) or np.shape(self.covariance) != (2 * n, 2 * n):
            raise ValueError(
                f"a prior map needs means (n, 2) and covariance (2n, 2n), got "
                f"{np.shape(self.means)} and {np.shape(self.covariance)}"
            )
        if len(self.sightings) != n:
            raise ValueError(f"{len(self.sightings)} sighting counts for {n} landmarks")


def prior_map(ekf: EKFSLAM) -> PriorMap:
    """The map `ekf` holds now, as a `PriorMap`: its means and the map block of Σ (the pose rows
    and columns dropped), symmetrised."""
    n, Sigma = ekf.n_landmarks, ekf.Sigma
    C = Sigma[3:, 3:]
    return PriorMap(
        means=ekf.mu[3:].reshape(n, 2).copy(),
        covariance=0.5 * (C + C.T),
        sightings=ekf.accepted_sightings(),
    )


def start_with(ekf: EKFSLAM, prior: PriorMap) -> EKFSLAM:
    """Put `prior`'s landmarks into `ekf`, a filter that has taken no step yet; returns it.

    Landmark j gets slot j and id j, its mean and covariance the prior's, and no correlation with
    the pose (eq. 2's Σ0 block stays the filter's own): `EKFSLAM.start_with_map`.
    """
    ekf.start_with_map(prior.means, prior.covariance, prior.sightings)
    return ekf


@dataclass(frozen=True)
class PassRecord:
    """One pass of `ekfslam.pipeline.replay` with ``passes`` > 1.

    cost : how badly the pass's map explains the sightings it was fed: the mean over its updates
        of their NIS (eq. 13's ν against S), a rejected one counted at the gate (a capped χ²);
        NaN with none. The replay keeps the pass with the smallest.
    changed : sightings decided otherwise than in the pass before (-1 for the first pass).
    """

    cost: float
    changed: int


def pass_record(
    history: History, gate: float | None, estimated: NDArray[np.int64], before=None
) -> PassRecord:
    """The `PassRecord` of a pass: the history of the filter that mapped its decisions, the
    filter's gate (None: no gate, nothing rejected), its decisions (N,) and the decisions of
    the pass before (None for the first)."""
    used = history.outcome_mask(Outcome.ACCEPTED)
    rejected = int(history.outcome_mask(Outcome.REJECTED).sum())
    total = int(used.sum()) + rejected
    capped = float(history.obs_nis[used].sum()) + (gate or 0.0) * rejected
    cost = capped / total if total else float("nan")
    changed = -1 if before is None else int(np.count_nonzero(np.asarray(before) != estimated))
    return PassRecord(cost=cost, changed=changed)
