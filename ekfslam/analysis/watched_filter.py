"""The filter exercise 8 hands the student's replay loop, and what the check reads of it.

`WatchedEKF` is the same filter as `EKFSLAM`, except that a motion noise that is not 3x3 or a
measurement noise that is not 2x2 stops the check with the names (ours and the seed's are
Thrun's, the reverse of filterpy's) instead of a bare shape error. `FilterUnderTest` is the
exercise's input: the loop gets the filter it builds and drives it; the judge gets its
`snapshot` afterwards (the state and the counts), in the notebook's check and from the grader's
sandbox alike.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.teaching.verdicts import Driven, Wrong

SWAPPED = (
    "ekf.{call} got a {shape} noise matrix: here, as in the seed and Thrun, R (3x3) is the motion "
    "noise that predict takes and Q (2x2) the measurement noise that update takes (filterpy's "
    "names are the other way round)."
)
#: the counts of `EKFSLAM.counts` a snapshot carries
COUNTS = ("predictions", "initialised", "accepted", "rejected", "refused", "reinitialised")


class WatchedEKF(EKFSLAM):
    """`EKFSLAM` that refuses R and Q swapped with a verdict naming them (see the module)."""

    def predict(self, u: ArrayLike, R: ArrayLike, t: float | None = None) -> None:
        shape = np.shape(R)
        if shape != (3, 3):
            raise Wrong(SWAPPED.format(call="predict", shape="x".join(map(str, shape))))
        super().predict(u, R, t)

    def update(self, landmark_id: int, z: ArrayLike, Q: ArrayLike, t: float | None = None):
        shape = np.shape(Q)
        if shape != (2, 2):
            raise Wrong(SWAPPED.format(call="update", shape="x".join(map(str, shape))))
        return super().update(landmark_id, z, Q, t)


@dataclass(frozen=True)
class FilterUnderTest(Driven):
    """A `WatchedEKF` started at `start` with `config`, for the student's loop to drive."""

    start: np.ndarray
    config: FilterConfig

    def build(self) -> WatchedEKF:
        return WatchedEKF(np.array(self.start, dtype=float), None, self.config)

    def snapshot(self, built: object) -> dict:
        """{"mu", "Sigma", "landmark_ids", "counts": {name: int}} of the filter `built`."""
        if not isinstance(built, EKFSLAM):
            raise Wrong("the filter the check gave your loop is gone")
        counts = {name: int(getattr(built.counts, name)) for name in COUNTS}
        ids = [int(i) for i in built.landmark_ids]
        return {
            "mu": built.mu.copy(),
            "Sigma": built.Sigma.copy(),
            "landmark_ids": ids,
            "counts": counts,
        }
