"""What the filter remembers of a run: the single source for every plot and metric.

The recorder keeps per event only O(1)-sized things (the pose, its 3x3 covariance, one
observation's numbers), never a copy of the n x n covariance, so a long run costs O(steps) memory.
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
OUTCOMES = ("initialised", "accepted", "rejected", "refused")
INITIALISED, ACCEPTED, REJECTED, REFUSED = range(4)


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


class Recorder:
    """Collects events as plain tuples (cheap appends) and freezes them into a History.

    Poses come as 3 floats, covariances flattened row-major (9 or 4 floats); absent values
    (a new landmark has no ẑ) as None.
    """

    def __init__(self) -> None:
        self._t: list[float] = []
        self._event: list[int] = []
        self._pose: list = []
        self._pose_cov: list = []
        self._obs: list[tuple] = []

    def event(self, t: float, kind: int, pose, pose_cov) -> None:
        self._t.append(t)
        self._event.append(kind)
        self._pose.append(pose)
        self._pose_cov.append(pose_cov)

    def observation(
        self, t, landmark_id, z, z_hat, innovation, S, nis, outcome, landmark, landmark_cov
    ) -> None:
        self._obs.append(
            (t, len(self._t) - 1, landmark_id, z, z_hat, innovation, S, nis, outcome,
             landmark, landmark_cov)
        )  # fmt: skip

    def finish(self) -> History:
        nan2, nan4 = (math.nan,) * 2, (math.nan,) * 4
        obs = self._obs

        def column(i: int, width: int, missing=None) -> Array:
            values = [missing if o[i] is None else o[i] for o in obs]
            return np.array(values, dtype=float).reshape(-1, width)

        return History(
            t=np.array(self._t, dtype=float),
            event=np.array(self._event, dtype=np.int8),
            pose=np.array(self._pose, dtype=float).reshape(-1, 3),
            pose_cov=np.array(self._pose_cov, dtype=float).reshape(-1, 3, 3),
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
