"""What the filter remembers of a run: the single source for every plot and metric.

The recorder keeps per event only O(1)-sized things (the pose, its 3x3 covariance, one
observation's numbers), never a copy of the n x n covariance, so a long run costs O(steps) memory:
about 100 bytes per event in the finished `History`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Event kinds in `History.event`.
PREDICT, OBSERVE = 0, 1
#: Observation outcomes in `History.obs_outcome` (index into this tuple).
OUTCOMES = ("initialised", "accepted", "rejected", "refused", "reinitialised")
INITIALISED, ACCEPTED, REJECTED, REFUSED, REINITIALISED = range(5)


@dataclass(frozen=True, eq=False)
class History:
    """Everything recorded during a run.

    Per event (K events: every prediction and every observation, in order)
        t (K,) s; event (K,) `PREDICT` or `OBSERVE`; pose (K, 3) the mean after the event;
        pose_cov (K, 3, 3) its covariance.
    Per observation (M observations)
        obs_t (M,), obs_event (M,) index into the per-event arrays, obs_id (M,) landmark id,
        obs_z (M, 2) measured (r, φ), obs_z_hat (M, 2) predicted (r, φ) before the update
        (NaN for a new landmark, which has no prediction), obs_innovation (M, 2) z - ẑ with the
        bearing wrapped, obs_S (M, 2, 2) innovation covariance, obs_nis (M,) νᵀ S⁻¹ ν,
        obs_outcome (M,) index into `OUTCOMES`, obs_landmark (M, 2) and obs_landmark_cov
        (M, 2, 2) that landmark's estimate after the event.
    """

    t: Array
    event: NDArray[np.int8]
    pose: Array
    pose_cov: Array
    obs_t: Array
    obs_event: NDArray[np.int64]
    obs_id: NDArray[np.int64]
    obs_z: Array
    obs_z_hat: Array
    obs_innovation: Array
    obs_S: Array
    obs_nis: Array
    obs_outcome: NDArray[np.int8]
    obs_landmark: Array
    obs_landmark_cov: Array

    def outcome_mask(self, outcome: str) -> NDArray[np.bool_]:
        """Boolean mask over observations with the given outcome name (see `OUTCOMES`)."""
        return self.obs_outcome == OUTCOMES.index(outcome)

    @property
    def nis_of_updates(self) -> Array:
        """NIS of the observations that were used as updates (accepted ones)."""
        return self.obs_nis[self.outcome_mask("accepted")]


#: Columns of one recorded event row: time, pose and the six distinct entries of its covariance.
ROW = ("t", "x", "y", "theta", "xx", "xy", "xtheta", "yy", "ytheta", "thetatheta")
#: Where each entry of the 3x3 pose covariance sits in a row's covariance part (ROW[4:]).
_COV_INDEX = np.array([0, 1, 2, 1, 3, 4, 2, 4, 5])


class Recorder:
    """Collects events as flat rows of Python floats (cheap appends) and freezes them at the end.

    An event is its kind and one row laid out as `ROW`: 10 floats, O(1) per event whatever the
    map size. All rows go into one flat list, which numpy turns into an array in one pass.
    Observations come as tuples (absent values, such as a new landmark's ẑ, as None).
    """

    def __init__(self) -> None:
        self._kinds: list[int] = []
        self._rows: list[float] = []
        self._obs: list[tuple] = []

    def event(self, kind: int, row: tuple[float, ...]) -> None:
        """One event of `kind` (`PREDICT` or `OBSERVE`); `row` as `ROW` (the state after it)."""
        self._kinds.append(kind)
        self._rows.extend(row)

    def events(self, kind: int, rows: list[float]) -> None:
        """Several events of one kind, their rows laid end to end in one flat list."""
        self._kinds.extend([kind] * (len(rows) // len(ROW)))
        self._rows.extend(rows)

    def observation(
        self, t, landmark_id, z, z_hat, innovation, S, nis, outcome, landmark, landmark_cov
    ) -> None:
        """What the last recorded event observed. Covariances as nested rows (2x2)."""
        self._obs.append(
            (t, len(self._kinds) - 1, landmark_id, z, z_hat, innovation, S, nis, outcome,
             landmark, landmark_cov)
        )  # fmt: skip

    def finish(self) -> History:
        nan2, nan4 = (math.nan,) * 2, (math.nan,) * 4
        obs = self._obs
        rows = np.array(self._rows, dtype=float).reshape(-1, len(ROW))

        def column(i: int, width: int, missing=None) -> Array:
            values = [missing if o[i] is None else o[i] for o in obs]
            return np.array(values, dtype=float).reshape(-1, width)

        return History(
            t=rows[:, 0].copy(),
            event=np.array(self._kinds, dtype=np.int8),
            pose=rows[:, 1:4].copy(),
            pose_cov=rows[:, 4:][:, _COV_INDEX].reshape(-1, 3, 3),
            obs_t=np.array([o[0] for o in obs], dtype=float),
            obs_event=np.array([o[1] for o in obs], dtype=np.int64),
            obs_id=np.array([o[2] for o in obs], dtype=np.int64),
            obs_z=column(3, 2),
            obs_z_hat=column(4, 2, nan2),
            obs_innovation=column(5, 2, nan2),
            obs_S=column(6, 4, nan4).reshape(-1, 2, 2),
            obs_nis=np.array([o[7] for o in obs], dtype=float),
            obs_outcome=np.array([o[8] for o in obs], dtype=np.int8),
            obs_landmark=column(9, 2),
            obs_landmark_cov=column(10, 4).reshape(-1, 2, 2),
        )
