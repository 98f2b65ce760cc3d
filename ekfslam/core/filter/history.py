"""What the filter remembers of a run: the single source for every plot and metric.

The recorder keeps per event only O(1)-sized things (the pose, its 3x3 covariance, one
observation's numbers), never a copy of the n x n covariance, so a long run costs O(steps) memory:
about 100 bytes per event in the finished `History`. Copies of the whole state are `Keyframes`,
a fixed number of them, taken only when a replay is asked for them (an animation's frames).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Event kinds in `History.event`.
PREDICT, OBSERVE = 0, 1


class Outcome(IntEnum):
    """What the filter did with one observation: the code in `History.obs_outcome`.

    The filter's steps (`ekfslam.core.filter.steps`) return these, compiled or not. `label` is
    the lower-case name that `FilterCounts` fields, JSON keys and printed counts use.

    INITIALISED: a new landmark entered the map (eq. 12). ACCEPTED: an update (eqs. 13-16).
    REJECTED: the NIS failed the gate. REFUSED: the landmark, or the observation, sits on the
    robot, so there is no bearing to linearise. REINITIALISED: a landmark placed again (see
    `FilterConfig.reinit_after`). SINGULAR: the innovation covariance S of eq. (15) is singular
    or not finite (noise so small that S underflows, or so large that it overflows), so there is
    no gain. DEFERRED: a sighting of a landmark not yet mapped by a sensor that needs two
    (a bearing alone, `ekfslam.core.models.SensorModel.triangulate`), held until a later one
    meets it with enough parallax to place the landmark (`ekfslam.core.initialisation`).
    """

    INITIALISED = 0
    ACCEPTED = 1
    REJECTED = 2
    REFUSED = 3
    REINITIALISED = 4
    SINGULAR = 5
    DEFERRED = 6

    @property
    def label(self) -> str:
        """The lower-case name ("accepted", ...): a `FilterCounts` field and a JSON key."""
        return self.name.lower()


@dataclass(frozen=True, eq=False)
class History:
    """Everything recorded during a run.

    Per event (K events: every prediction and every observation, in order)
        t (K,) s; event (K,) `PREDICT` or `OBSERVE`; pose (K, 3) the mean after the event;
        pose_cov (K, 3, 3) its covariance.
    Per observation (M observations)
        obs_t (M,), obs_event (M,) index into the per-event arrays, obs_id (M,) landmark id,
        obs_z (M, m) measured (r, φ for the seed's sensor; m the sensor's `SensorModel.size`),
        obs_z_hat (M, m) predicted before the update (NaN for a new landmark, which has no
        prediction), obs_innovation (M, m) z - ẑ with the bearing wrapped, obs_S (M, m, m)
        innovation covariance, obs_nis (M,) νᵀ S⁻¹ ν,
        obs_outcome (M,) an `Outcome` code, obs_landmark (M, 2) and obs_landmark_cov
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

    def outcome_mask(self, *outcomes: Outcome) -> NDArray[np.bool_]:
        """Boolean mask (M,) over the observations with any of the given outcomes."""
        return np.isin(self.obs_outcome, outcomes)

    @property
    def nis_of_updates(self) -> Array:
        """NIS of the observations that were used as updates (accepted ones)."""
        return self.obs_nis[self.outcome_mask(Outcome.ACCEPTED)]


@dataclass(frozen=True, eq=False)
class Keyframes:
    """The full state at a few moments of a replay: what `History` leaves out, for animations.

    `History` keeps O(1) per event; the landmarks' estimates between their own sightings and the
    correlations of Σ are in no event. A keyframe is a copy of μ and Σ, O(n²), so a replay
    records them only when asked (`ekfslam.pipeline.replay`'s ``keyframes``), a fixed number
    whatever the run's length: F keyframes of a state of size D cost 8 F D² bytes.

    F keyframes, D = 3 + 2n the size of the final state
        t (F,) s, the time of the state; detections (F,) how many detections it has used;
        dim (F,) its size 3 + 2 n_f; mu (F, D) and Sigma (F, D, D), eqs. (1)-(2)'s mean and
        covariance, NaN beyond dim (the landmarks not yet seen); landmark_ids (n,) the ids in
        slot order (a slot keeps its landmark: keyframe f holds the first (dim_f - 3) / 2).
    The last keyframe is the final state.
    """

    t: Array
    detections: NDArray[np.int64]
    dim: NDArray[np.int64]
    mu: Array
    Sigma: Array
    landmark_ids: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.t)


class KeyframeRecorder:
    """Collects `Keyframes`: `take` copies the state at chosen moments; `finish` pads, freezes."""

    def __init__(self) -> None:
        self._t: list[float] = []
        self._detections: list[int] = []
        self._mu: list[Array] = []
        self._Sigma: list[Array] = []

    def take(self, t: float, detections: int, mu: Array, Sigma: Array) -> None:
        """Keep copies of mu (d,) and Sigma (d, d) at time t (s), after `detections` detections."""
        self._t.append(float(t))
        self._detections.append(int(detections))
        self._mu.append(np.array(mu, dtype=float))
        self._Sigma.append(np.array(Sigma, dtype=float))

    def finish(self, landmark_ids: list[int]) -> Keyframes:
        dims = np.array([len(m) for m in self._mu], dtype=np.int64)
        D = int(dims.max()) if len(dims) else 3
        mu = np.full((len(dims), D), np.nan)
        Sigma = np.full((len(dims), D, D), np.nan)
        for f, d in enumerate(dims):
            mu[f, :d] = self._mu[f]
            Sigma[f, :d, :d] = self._Sigma[f]
        return Keyframes(
            t=np.array(self._t),
            detections=np.array(self._detections, dtype=np.int64),
            dim=dims,
            mu=mu,
            Sigma=Sigma,
            landmark_ids=np.array(landmark_ids, dtype=np.int64),
        )


#: Columns of one recorded event row: time, pose and the six distinct entries of its covariance.
ROW = ("t", "x", "y", "theta", "xx", "xy", "xtheta", "yy", "ytheta", "thetatheta")
#: The columns every observation row has, whatever the measurement's size: time, the index of
#: its event, the landmark id, the NIS, the outcome (an `Outcome` code), the landmark's mean and
#: covariance after it (2x2, row-major).
OBS_FIXED = ("t", "event", "id", "nis", "outcome", "mx", "my", "Mxx", "Mxy", "Myx", "Myy")


def obs_row(size: int) -> tuple[str, ...]:
    """Columns of one recorded observation row for a measurement of `size` numbers (NaN where a
    value is absent, such as a new landmark's ẑ): `OBS_FIXED`, then z, ẑ, ν (`size` each) and
    S (size x size, row-major): 11 + 3 m + m² floats, 21 for the seed's range and bearing."""
    m = range(size)
    return (
        *OBS_FIXED,
        *(f"z{i}" for i in m),
        *(f"z_hat{i}" for i in m),
        *(f"nu{i}" for i in m),
        *(f"S{i}{j}" for i in m for j in m),
    )


def obs_width(size: int) -> int:
    """How many floats an observation row of a `size`-number measurement holds (`obs_row`)."""
    return len(OBS_FIXED) + 3 * size + size * size


#: The seed's observation row: z = (r, φ).
OBS_ROW = obs_row(2)


def _span(names: tuple[str, ...], first: str, last: str) -> slice:
    """The columns from `first` to `last` (inclusive) of a row laid out as `names`."""
    return slice(names.index(first), names.index(last) + 1)


class RowColumns(NamedTuple):
    """Where the parts of an event row (`ROW`) sit: a column index or a slice of columns."""

    t: int
    pose: slice  # x, y, θ
    cov: slice  # the six distinct entries of the 3x3 pose covariance (`_COV_INDEX`)


class ObsColumns(NamedTuple):
    """Where each `History.obs_*` field sits in an observation row (`obs_row`)."""

    t: int
    event: int
    id: int
    z: slice
    z_hat: slice
    innovation: slice
    S: slice  # m x m, row-major
    nis: int
    outcome: int
    landmark: slice
    landmark_cov: slice  # 2x2, row-major


def obs_columns(size: int) -> ObsColumns:
    """Where each part of an observation row of a `size`-number measurement sits."""
    names, last = obs_row(size), size - 1
    return ObsColumns(
        t=names.index("t"),
        event=names.index("event"),
        id=names.index("id"),
        z=_span(names, "z0", f"z{last}"),
        z_hat=_span(names, "z_hat0", f"z_hat{last}"),
        innovation=_span(names, "nu0", f"nu{last}"),
        S=_span(names, "S00", f"S{last}{last}"),
        nis=names.index("nis"),
        outcome=names.index("outcome"),
        landmark=_span(names, "mx", "my"),
        landmark_cov=_span(names, "Mxx", "Myy"),
    )


ROW_COLUMNS = RowColumns(
    t=ROW.index("t"), pose=_span(ROW, "x", "theta"), cov=_span(ROW, "xx", "thetatheta")
)
OBS_COLUMNS = obs_columns(2)
#: Where the steps write (`ekfslam.core.filter.steps`): each part's first column in a row. The
#: measurement's part starts at OBS_Z: z at OBS_Z, ẑ at OBS_Z + m, ν at OBS_Z + 2 m, S at
#: OBS_Z + 3 m, for z of m numbers (`obs_row`).
ROW_T, ROW_POSE, ROW_COV = ROW.index("t"), ROW.index("x"), ROW.index("xx")
OBS_T, OBS_EVENT, OBS_ID, OBS_NIS = (OBS_FIXED.index(c) for c in ("t", "event", "id", "nis"))
OBS_OUTCOME, OBS_LANDMARK, OBS_LANDMARK_COV = (OBS_FIXED.index(c) for c in ("outcome", "mx", "Mxx"))
OBS_Z = len(OBS_FIXED)
#: Where each entry of the 3x3 pose covariance sits in a row's covariance part (`ROW_COLUMNS.cov`).
_COV_INDEX = np.array([0, 1, 2, 1, 3, 4, 2, 4, 5])


class Recorder:
    """Collects events in pre-allocated arrays that double when full, and freezes them at the end.

    An event is its kind and one row laid out as `ROW`: 10 floats, O(1) per event whatever the
    map size; an observation adds one row laid out as `obs_row(size)`, size the number of
    values in a measurement (2, the seed's range and bearing, by default). The filter's steps
    (`ekfslam.core.filter.steps`) write the rows in place: `reserve` says where.
    """

    def __init__(self, capacity: int = 1024, size: int = 2) -> None:
        self.rows = np.empty((capacity, len(ROW)))
        self.kinds = np.empty(capacity, dtype=np.int8)
        self.n = 0  # events so far
        self.size = size
        self.obs = np.empty((capacity, obs_width(size)))
        self.m = 0  # observations so far

    def reserve(self, kind: int, count: int) -> int:
        """Make room for `count` events of `kind`; returns the index of the first one's row."""
        n = self.n
        if n + count > len(self.kinds):
            size = max(2 * len(self.kinds), n + count)
            self.rows = _grown(self.rows, size, n)
            self.kinds = _grown(self.kinds, size, n)
        if count == 1:  # an observation: a scalar store, a quarter of a slice's cost
            self.kinds[n] = kind
        else:
            self.kinds[n : n + count] = kind
        self.n = n + count
        return n

    def room(self, events: int, observations: int) -> None:
        """Make room for `events` more events and `observations` more observations, reserving
        none (`ekfslam.core.filter.steps.feed` writes them, and says how many it wrote)."""
        if self.n + events > len(self.kinds):
            size = max(2 * len(self.kinds), self.n + events)
            self.rows = _grown(self.rows, size, self.n)
            self.kinds = _grown(self.kinds, size, self.n)
        if self.m + observations > len(self.obs):
            self.obs = _grown(self.obs, max(2 * len(self.obs), self.m + observations), self.m)

    def reserve_observation(self) -> int:
        """Make room for one observation (after its event's `reserve`); returns its row index."""
        m = self.m
        if m == len(self.obs):
            self.obs = _grown(self.obs, 2 * m, m)
        self.m = m + 1
        return m

    def finish(self) -> History:
        rows, obs = self.rows[: self.n], self.obs[: self.m]
        r, o, m = ROW_COLUMNS, obs_columns(self.size), self.size
        return History(
            t=rows[:, r.t].copy(),
            event=self.kinds[: self.n].copy(),
            pose=rows[:, r.pose].copy(),
            pose_cov=rows[:, r.cov][:, _COV_INDEX].reshape(-1, 3, 3),
            obs_t=obs[:, o.t].copy(),
            obs_event=obs[:, o.event].astype(np.int64),
            obs_id=obs[:, o.id].astype(np.int64),
            obs_z=obs[:, o.z].copy(),
            obs_z_hat=obs[:, o.z_hat].copy(),
            obs_innovation=obs[:, o.innovation].copy(),
            obs_S=obs[:, o.S].reshape(-1, m, m).copy(),
            obs_nis=obs[:, o.nis].copy(),
            obs_outcome=obs[:, o.outcome].astype(np.int8),
            obs_landmark=obs[:, o.landmark].copy(),
            obs_landmark_cov=obs[:, o.landmark_cov].reshape(-1, 2, 2).copy(),
        )


def _grown(a: NDArray, size: int, used: int) -> NDArray:
    """A larger copy of `a` along its first axis, keeping its first `used` entries."""
    b = np.empty((size, *a.shape[1:]), dtype=a.dtype)
    b[:used] = a[:used]
    return b
