"""The filter's storage and how it is read: the mean and covariance of eqs. (1)-(2), pre-allocated.

`FilterState` holds μ and Σ in storage that grows geometrically, so adding a landmark never
copies the matrix (except on the rare doubling of the capacity); the storage beyond the state is
kept at zero, and the steps keep only Σ's lower triangle current (`ekfslam.core.filter.kernels`).
It owns the slots (landmark id -> slot j, state rows 3 + 2j and 4 + 2j), the counts and the
recorder, and everything a reader asks of the filter: μ, Σ, the pose, a landmark, the map, the
history.

With `linearization="invariant"` the storage holds the covariance P of the right-invariant error
ξ (`ekfslam.core.invariant`): every covariance handed out is the Cartesian T P Tᵀ, to first
order, and `invariant_covariance` is P itself; the map block may still owe the prediction's
heading noise, which `_settle` adds before Σ is read.

`ekfslam.core.filter.ekf.EKFSLAM` is this state with the steps of the seed's algorithm.
"""

from __future__ import annotations

import copy
from dataclasses import fields
from typing import Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter import kernels
from ekfslam.core.filter.config import FilterConfig, FilterCounts
from ekfslam.core.filter.history import History, Recorder
from ekfslam.core.filter_checks import check_start
from ekfslam.core.invariant import from_cartesian, landmark_to_cartesian, to_cartesian

Array = NDArray[np.float64]


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
        cap = 3 + 2 * self.config.initial_capacity
        self._mu = np.zeros(cap)
        self._Sigma = np.zeros((cap, cap))
        self._dim = 3
        self._mu[:3] = np.asarray(pose, dtype=float)
        self._mu[2] = kernels.wrap(float(self._mu[2]))
        # invariant: _Sigma holds the covariance of the right-invariant error (`core.invariant`)
        self._invariant = self.config.linearization == "invariant"
        if pose_covariance is not None:
            P0 = np.asarray(pose_covariance, dtype=float)
            if self._invariant:  # Σ0 is Cartesian; the filter keeps ξ's
                P0 = from_cartesian(P0, self._mu[:3])
            self._Sigma[:3, :3] = 0.5 * (P0 + P0.T)
        self._ids: list[int] = []
        self.slot: dict[int, int] = {}
        self._counts = dict.fromkeys((f.name for f in fields(FilterCounts)), 0)
        self._recorder = Recorder() if record else None
        # invariant: the map block still owes rho v vᵀ up to row _owed_to (`kernels.propagate`)
        self._rho, self._owed_to = 0.0, 3
        # scratch for the kernels (filled in place): H Σ, then W = L⁻¹ H Σ; the invariant v
        self._work = np.zeros((3, cap))

    def clone(self) -> Self:
        """An independent copy of the state, without a history: one hypothesis of
        `ekfslam.core.filter.mht` (O(capacity²), the storage of Σ; nothing else is that big)."""
        c = copy.copy(self)
        c._mu, c._Sigma, c._work = self._mu.copy(), self._Sigma.copy(), self._work.copy()
        c._ids, c.slot, c._counts = list(self._ids), dict(self.slot), dict(self._counts)
        c._recorder = None
        return c

    # ------------------------------------------------------------------ views
    @property
    def mu(self) -> Array:
        """The state mean (3 + 2n,), eq. (1). A view: do not resize."""
        return self._mu[: self._dim]

    @property
    def Sigma(self) -> Array:
        """The state covariance (3 + 2n, 3 + 2n), a view into the pre-allocated storage.

        The steps keep only its lower triangle current (`ekfslam.core.filter.kernels`); reading it
        fills in the upper one, O(n²). Read it again after a step rather than keeping the view.
        With `linearization="invariant"` it is the Cartesian covariance of (x, y, θ, m), a new
        array, T P Tᵀ from `invariant_covariance` (`ekfslam.core.invariant.to_cartesian`).
        """
        self._settle()
        kernels.mirror(self._Sigma, self._dim)
        P = self._Sigma[: self._dim, : self._dim]
        return to_cartesian(P, self.mu) if self._invariant else P

    @property
    def invariant_covariance(self) -> Array:
        """The covariance the invariant filter keeps, of its right-invariant error ξ (a copy)."""
        if not self._invariant:
            raise AttributeError("only a filter with linearization='invariant' has one")
        self._settle()
        kernels.mirror(self._Sigma, self._dim)
        return self._Sigma[: self._dim, : self._dim].copy()

    @property
    def pose(self) -> Array:
        """(x, y, θ), a copy."""
        return self._mu[:3].copy()

    @property
    def pose_covariance(self) -> Array:
        """The 3x3 pose block of Sigma (Cartesian for the invariant filter too), a copy."""
        P = self._Sigma[:3, :3].copy()
        return to_cartesian(P, self._mu[:3]) if self._invariant else P

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
        return (self._mu.shape[0] - 3) // 2

    @property
    def counts(self) -> FilterCounts:
        return FilterCounts(**self._counts)

    def landmark(self, landmark_id: int) -> tuple[Array, Array]:
        """Mean (2,) and covariance (2, 2) of one landmark, by id (copies)."""
        l = 3 + 2 * self.slot[landmark_id]
        self._settle()
        (a, _), (b, c) = self._Sigma[l : l + 2, l : l + 2].tolist()  # its lower triangle
        m, P = self._mu[l : l + 2].copy(), np.array([[a, b], [b, c]])
        if self._invariant:
            P = landmark_to_cartesian(P, self._Sigma[l : l + 2, 2], self._Sigma[2, 2], m)
        return m, P

    def landmark_map(self) -> dict[int, Array]:
        """{landmark id: mean (2,)}, the estimated map."""
        return {i: self._mu[3 + 2 * j : 5 + 2 * j].copy() for j, i in enumerate(self._ids)}

    def history(self) -> History:
        """Everything recorded so far (raises if the filter was built with record=False)."""
        if self._recorder is None:
            raise RuntimeError("this filter was built with record=False")
        return self._recorder.finish()

    def _settle(self) -> None:
        """Add the heading noise the invariant filter's map block is owed (O(n²), see
        `kernels.propagate`); a correction adds it in its own pass instead."""
        if self._rho:
            kernels.spread(self._mu, self._Sigma, self._owed_to, self._rho, self._work[2])
            self._rho = 0.0

    def _grow(self) -> None:
        d = self._dim
        cap = 3 + 2 * (2 * self.capacity)
        mu = np.zeros(cap)
        S = np.zeros((cap, cap))
        mu[:d] = self._mu[:d]
        S[:d, :d] = self._Sigma[:d, :d]
        self._mu, self._Sigma = mu, S
        self._work = np.zeros((3, cap))
