"""The filter's storage and how it is read: the mean and covariance of eqs. (1)-(2), pre-allocated.

`FilterState` holds μ and Σ (`ekfslam.core.filter.steps.Storage`) in arrays that grow
geometrically, so adding a landmark never copies the matrix (except on the rare doubling of the
capacity); the storage beyond the state is kept at zero, and the steps keep both of Σ's
triangles current (`ekfslam.core.filter.symmetric`): any read of it, a kept view included, is
the current value. It owns the slots (landmark id -> slot j,
state rows 3 + 2j and 4 + 2j), the counts and the recorder, the step functions it runs
(`ekfslam.core.filter.backend`), and everything a reader asks of the filter: μ, Σ, the pose, a
landmark, the map, the history.

With `linearization="invariant"` the storage holds the covariance P of the right-invariant error
ξ (`ekfslam.core.invariant`): every covariance handed out is the Cartesian T P Tᵀ, to first
order, and `invariant_covariance` is P itself; the map block may still owe the prediction's
heading noise, which `steps.settle` adds before Σ is read.

`ekfslam.core.filter.ekf.EKFSLAM` is this state with the decisions of the seed's algorithm.
"""

from __future__ import annotations

import copy
import math
import types
from dataclasses import fields
from typing import Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter.backend import auto_steps, steps_for
from ekfslam.core.filter.config import FilterConfig, FilterCounts
from ekfslam.core.filter.history import History, Recorder
from ekfslam.core.filter.steps import Linearization, Storage
from ekfslam.core.filter.symmetric import diagonal_block
from ekfslam.core.filter_checks import check_start
from ekfslam.core.invariant import from_cartesian, landmark_to_cartesian, to_cartesian
from ekfslam.core.models import ODOMETRY, RANGE_BEARING
from ekfslam.geometry import wrap_angle

Array = NDArray[np.float64]

#: How often (events) a filter on backend "auto" asks whether the compiled steps pay (`_ran`).
LOOK_EVERY = 1000


def _storage(capacity: int, linearization: int) -> Storage:
    """Zeroed arrays for a state of up to `capacity` landmarks."""
    cap = 3 + 2 * capacity
    return Storage(np.zeros(cap), np.zeros((cap, cap)), np.zeros(cap), np.zeros(2), linearization)


class FilterState:
    """The filter's mean, covariance, slots and counts, and the views of them (see the module).

    Parameters
    ----------
    pose : array (3,)
        Initial pose (x, y, θ) in m, m, rad: μ0 of eq. (1).
    pose_covariance : array (3, 3), optional
        Σ0 of eq. (2); zero (a known start, as in the seed) by default.
    config : FilterConfig
    record : bool
        Keep a `History` (default). Turn off for benchmarks of the bare filter.
    """

    def __init__(
        self,
        pose: ArrayLike,
        pose_covariance: ArrayLike | None = None,
        config: FilterConfig | None = None,
        record: bool = True,
    ) -> None:
        check_start(pose, pose_covariance, config, record)
        self.config = config or FilterConfig()
        lin = Linearization[self.config.linearization.upper()]
        self._use(_storage(self.config.initial_capacity, int(lin)))
        self._invariant = lin == Linearization.INVARIANT
        self._dim = 3
        mu = self._storage.mu
        mu[:3] = np.asarray(pose, dtype=float)
        mu[2] = wrap_angle(mu[2])
        self._storage.first[:3] = mu[:3]
        if pose_covariance is not None:
            P0 = np.asarray(pose_covariance, dtype=float)
            if self._invariant:  # Σ0 is Cartesian; the filter keeps ξ's
                P0 = from_cartesian(P0, mu[:3])
            self._storage.Sigma[:3, :3] = 0.5 * (P0 + P0.T)
        self._ids: list[int] = []
        self.slot: dict[int, int] = {}
        self._counts = dict.fromkeys((f.name for f in fields(FilterCounts)), 0)
        self.motion = self.config.motion or ODOMETRY
        self.sensor = self.config.sensor or RANGE_BEARING
        self._recorder = Recorder(size=self.sensor.size) if record else None
        self._events = 0  # run on the Python steps since "auto" last looked (`auto_steps`)
        self._look_at = math.inf  # ... when it looks again
        if self.config.backend == "auto":
            self._steps = auto_steps(self.motion, self.sensor, 0)
            if self._steps is None:
                self._steps = steps_for(self.motion, self.sensor, "python")
                self._look_at = LOOK_EVERY
        else:
            self._steps = steps_for(self.motion, self.sensor, self.config.backend)

    def clone(self) -> Self:
        """An independent copy of the state, without a history: one hypothesis of
        `ekfslam.core.filter.mht` (O(capacity²), the storage of Σ; nothing else is that big)."""
        c = copy.copy(self)
        s = self._storage
        c._use(Storage(s.mu.copy(), s.Sigma.copy(), s.first.copy(), s.owed.copy(), s.linearization))
        c._ids, c.slot, c._counts = list(self._ids), dict(self.slot), dict(self._counts)
        c._recorder = None
        return c

    # ------------------------------------------------------------------ views
    @property
    def steps(self) -> types.SimpleNamespace:
        """The step functions this filter runs: `ekfslam.core.filter.steps` and its kin, as
        Python or compiled (`FilterConfig.backend`), for its models."""
        return self._steps

    @property
    def mu(self) -> Array:
        """The state mean (3 + 2n,), eq. (1). A view: do not resize."""
        return self._storage.mu[: self._dim]

    @property
    def Sigma(self) -> Array:
        """The state covariance (3 + 2n, 3 + 2n), a view into the pre-allocated storage.

        Both triangles are current after every step (`ekfslam.core.filter.symmetric`), so a
        kept view reads the current Σ (until the storage grows: read it again after a landmark
        is added). With `linearization="invariant"` it is the Cartesian covariance of (x, y, θ, m),
        a new array, T P Tᵀ from `invariant_covariance` (`ekfslam.core.invariant.to_cartesian`).
        """
        self.settle()
        P = self._storage.Sigma[: self._dim, : self._dim]
        return to_cartesian(P, self.mu) if self._invariant else P

    @property
    def invariant_covariance(self) -> Array:
        """The covariance the invariant filter keeps, of its right-invariant error ξ (a copy)."""
        if not self._invariant:
            raise AttributeError("only a filter with linearization='invariant' has one")
        self.settle()
        return self._storage.Sigma[: self._dim, : self._dim].copy()

    @property
    def pose(self) -> Array:
        """(x, y, θ), a copy."""
        return self._storage.mu[:3].copy()

    @property
    def pose_covariance(self) -> Array:
        """The 3x3 pose block of Sigma (Cartesian for the invariant filter too), a copy."""
        P = diagonal_block(self._storage.Sigma, 0, 3)
        return to_cartesian(P, self._storage.mu[:3]) if self._invariant else P

    @property
    def n_landmarks(self) -> int:
        return len(self._ids)

    @property
    def landmark_ids(self) -> list[int]:
        """Landmark ids in slot order."""
        return list(self._ids)

    @property
    def capacity(self) -> int:
        """How many landmarks fit before the storage doubles."""
        return (self._storage.mu.shape[0] - 3) // 2

    @property
    def counts(self) -> FilterCounts:
        return FilterCounts(**self._counts)

    def landmark(self, landmark_id: int) -> tuple[Array, Array]:
        """Mean (2,) and covariance (2, 2) of one landmark, by id (copies)."""
        l = 3 + 2 * self.slot[landmark_id]
        self.settle()
        Sigma = self._storage.Sigma
        m = self._storage.mu[l : l + 2].copy()
        P = diagonal_block(Sigma, l, 2)
        if self._invariant:
            P = landmark_to_cartesian(P, Sigma[2, l : l + 2], Sigma[2, 2], m)
        return m, P

    def landmark_map(self) -> dict[int, Array]:
        """{landmark id: mean (2,)}, the estimated map."""
        mu = self._storage.mu
        return {i: mu[3 + 2 * j : 5 + 2 * j].copy() for j, i in enumerate(self._ids)}

    def history(self) -> History:
        """Everything recorded so far (raises if the filter was built with record=False)."""
        if self._recorder is None:
            raise RuntimeError("this filter was built with record=False")
        return self._recorder.finish()

    def settle(self) -> None:
        """Add the heading noise the invariant filter's map block is owed (O(n²), see
        `ekfslam.core.filter.steps.settle`); a correction adds it in its own pass instead."""
        if self._storage.owed[0]:
            self._steps.settle(self._arrays, self._dim)

    def _ran(self, events: int) -> None:
        """Count events run on the Python steps of backend "auto"; every `LOOK_EVERY`, ask
        whether the compiled steps pay now (`ekfslam.core.filter.backend.auto_steps`) and take
        them if so: the numbers stay the same to rounding, the rest of the run is faster."""
        self._events += events
        if self._events >= self._look_at:
            steps = auto_steps(self.motion, self.sensor, self._events)
            self._events = 0
            if steps is not None:
                self._steps, self._look_at = steps, math.inf

    def _grow(self) -> None:
        d, old = self._dim, self._storage
        new = _storage(2 * self.capacity, old.linearization)
        new.mu[:d], new.first[:d], new.owed[:] = old.mu[:d], old.first[:d], old.owed
        new.Sigma[:d, :d] = old.Sigma[:d, :d]
        self._use(new)

    def _use(self, storage: Storage) -> None:
        """Keep `storage`, and the plain tuple of it the steps are called with (numba dispatches
        on a tuple in a third of a named tuple's time, `ekfslam.core.filter.steps`)."""
        self._storage = storage
        self._arrays = tuple(storage)
