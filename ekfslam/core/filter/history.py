"""What the filter remembers of a run: the single source for every plot and metric.

The recorder keeps per event only O(1)-sized things (the pose, its 3x3 covariance, one
observation's numbers), never a copy of the n x n covariance, so a long run costs O(steps) memory:
about 100 bytes per event in the finished `History`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Event kinds in `History.event`.
PREDICT, OBSERVE = 0, 1
#: Observation outcomes in `History.obs_outcome` (index into this tuple). "refused": the
#: landmark (or the observation) sits on the robot, so there is no bearing to linearise;
#: "singular": the innovation covariance S of eq. (15) is singular or not finite (noise so
#: small that S underflows, or so large that it overflows), so there is no gain.
OUTCOMES = ("initialised", "accepted", "rejected", "refused", "reinitialised", "singular")
INITIALISED, ACCEPTED, REJECTED, REFUSED, REINITIALISED, SINGULAR = range(6)


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
#: Columns of one recorded observation row (NaN where a value is absent, such as a new
#: landmark's ẑ): time, the index of its event, the landmark id, z, ẑ, ν, S (2x2, row-major),
#: the NIS, the outcome (index into `OUTCOMES`), the landmark's mean and covariance after it.
OBS_ROW = (
    "t", "event", "id", "r", "phi", "r_hat", "phi_hat", "nu_r", "nu_phi",
    "S00", "S01", "S10", "S11", "nis", "outcome", "mx", "my", "Mxx", "Mxy", "Myx", "Myy",
)  # fmt: skip
#: Where each entry of the 3x3 pose covariance sits in a row's covariance part (ROW[4:]).
_COV_INDEX = np.array([0, 1, 2, 1, 3, 4, 2, 4, 5])


class Recorder:
    """Collects events in pre-allocated arrays that double when full, and freezes them at the end.

    An event is its kind and one row laid out as `ROW`: 10 floats, O(1) per event whatever the
    map size; an observation adds one row laid out as `OBS_ROW`. The filter's compiled kernels
    (`ekfslam.core.filter.kernels`) write the rows in place: `reserve` says where.
    """

    def __init__(self, capacity: int = 1024) -> None:
        self.rows = np.empty((capacity, len(ROW)))
        self.kinds = np.empty(capacity, dtype=np.int8)
        self.n = 0  # events so far
        self.obs = np.empty((capacity, len(OBS_ROW)))
        self.m = 0  # observations so far

    def reserve(self, kind: int, count: int) -> int:
        """Make room for `count` events of `kind`; returns the index of the first one's row."""
        n = self.n
        if n + count > len(self.kinds):
            size = max(2 * len(self.kinds), n + count)
            self.rows = _grown(self.rows, size, n)
            self.kinds = _grown(self.kinds, size, n)
        self.kinds[n : n + count] = kind
        self.n = n + count
        return n

    def reserve_observation(self) -> int:
        """Make room for one observation (after its event's `reserve`); returns its row index."""
        m = self.m
        if m == len(self.obs):
            self.obs = _grown(self.obs, 2 * m, m)
        self.m = m + 1
        return m

    def finish(self) -> History:
        rows, obs = self.rows[: self.n], self.obs[: self.m]
        return History(
            t=rows[:, 0].copy(),
            event=self.kinds[: self.n].copy(),
            pose=rows[:, 1:4].copy(),
            pose_cov=rows[:, 4:][:, _COV_INDEX].reshape(-1, 3, 3),
            obs_t=obs[:, 0].copy(),
            obs_event=obs[:, 1].astype(np.int64),
            obs_id=obs[:, 2].astype(np.int64),
            obs_z=obs[:, 3:5].copy(),
            obs_z_hat=obs[:, 5:7].copy(),
            obs_innovation=obs[:, 7:9].copy(),
            obs_S=obs[:, 9:13].reshape(-1, 2, 2).copy(),
            obs_nis=obs[:, 13].copy(),
            obs_outcome=obs[:, 14].astype(np.int8),
            obs_landmark=obs[:, 15:17].copy(),
            obs_landmark_cov=obs[:, 17:21].reshape(-1, 2, 2).copy(),
        )


def _grown(a: NDArray, size: int, used: int) -> NDArray:
    """A larger copy of `a` along its first axis, keeping its first `used` entries."""
    b = np.empty((size, *a.shape[1:]), dtype=a.dtype)
    b[:used] = a[:used]
    return b
