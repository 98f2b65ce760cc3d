"""What the filter remembers of a run: the single source for every plot and metric.

The recorder keeps per event only O(1)-sized things (the pose, its 3x3 covariance, one
observation's numbers), never a copy of the n x n covariance, so a long run costs O(steps) memory.
"""

from __future__ import annotations

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
    """Collects events as plain Python lists (cheap appends) and freezes them into a History."""

    def __init__(self) -> None:
        self._t: list[float] = []
        self._event: list[int] = []
        self._pose: list[Array] = []
        self._pose_cov: list[Array] = []
        self._obs: list[tuple] = []

    def event(self, t: float, kind: int, mu: Array, Sigma: Array) -> None:
        self._t.append(t)
        self._event.append(kind)
        self._pose.append(mu[:3].copy())
        self._pose_cov.append(Sigma[:3, :3].copy())

    def observation(
        self,
        t: float,
        landmark_id: int,
        z: Array,
        z_hat: Array | None,
        innovation: Array | None,
        S: Array | None,
        nis: float,
        outcome: int,
        landmark: Array,
        landmark_cov: Array,
    ) -> None:
        self._obs.append(
            (t, len(self._t) - 1, landmark_id, z, z_hat, innovation, S, nis, outcome,
             landmark, landmark_cov)
        )  # fmt: skip

    def finish(self) -> History:
        nan2, nan22 = np.full(2, np.nan), np.full((2, 2), np.nan)
        obs = self._obs
        return History(
            t=np.array(self._t, dtype=float),
            event=np.array(self._event, dtype=np.int8),
            pose=np.array(self._pose, dtype=float).reshape(-1, 3),
            pose_cov=np.array(self._pose_cov, dtype=float).reshape(-1, 3, 3),
            obs_t=np.array([o[0] for o in obs], dtype=float),
            obs_event=np.array([o[1] for o in obs], dtype=np.int64),
            obs_id=np.array([o[2] for o in obs], dtype=np.int64),
            obs_z=np.array([o[3] for o in obs], dtype=float).reshape(-1, 2),
            obs_z_hat=np.array([nan2 if o[4] is None else o[4] for o in obs]).reshape(-1, 2),
            obs_innovation=np.array([nan2 if o[5] is None else o[5] for o in obs]).reshape(-1, 2),
            obs_S=np.array([nan22 if o[6] is None else o[6] for o in obs]).reshape(-1, 2, 2),
            obs_nis=np.array([o[7] for o in obs], dtype=float),
            obs_outcome=np.array([o[8] for o in obs], dtype=np.int8),
            obs_landmark=np.array([o[9] for o in obs], dtype=float).reshape(-1, 2),
            obs_landmark_cov=np.array([o[10] for o in obs], dtype=float).reshape(-1, 2, 2),
        )
