"""The EKF-SLAM filter: the seed's algorithm (eqs. 1-16), touching only the blocks it needs.

State (eq. 1): mu = (x, y, θ, m1x, m1y, ..., mnx, mny), shape (3 + 2n,), and its covariance
Sigma, shape (3 + 2n, 3 + 2n). Landmarks get a slot the first time their id is seen; slot j
occupies indices 3 + 2j and 4 + 2j.

This class keeps the decisions: which slot an id has, whether a sighting is gated, when a
landmark is placed again, what is counted and recorded. The arithmetic of every step is
`ekfslam.core.filter.steps`, in block form (``Sigma[r, m] = G @ Sigma[r, m]``, eqs. cited on
the lines), run as written or compiled by numba from that same source
(`FilterConfig.backend`, `ekfslam.core.filter.backend`); the models it calls are
`FilterConfig.motion` and `FilterConfig.sensor` (`ekfslam.core.models`). The seed writes the
same steps with the lift matrices F_x (eq. 8) and F_x,j (eq. 14); `ekfslam.teaching.reference`
is that literal form, kept as the test oracle.

Cost per step with n landmarks: prediction O(n) (only the pose rows and columns change), update
O(n²) (one symmetric low-rank correction of Σ, in one pass), landmark initialisation O(n).
`python -m benchmarks bench` measures it.

With `FilterConfig(linearization="invariant")` (Barrau & Bonnabel 2015) the storage holds the
covariance P of the right-invariant error ξ (`ekfslam.core.invariant`) instead of Σ: the mean is
the same (x, y, θ, m), every covariance handed out is the Cartesian T P Tᵀ to first order
(`FilterState`), and `invariant_covariance` is P itself.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter.config import CHI2_2DOF_99 as CHI2_2DOF_99
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.delayed import Clones
from ekfslam.core.filter.history import (
    OBS_OUTCOME,
    OBS_ROW,
    OBSERVE,
    PREDICT,
    ROW,
    Outcome,
    obs_width,
)
from ekfslam.core.filter.predictions import Predicted, Rate, nearest_of, predictions_of
from ekfslam.core.filter.state import FilterState
from ekfslam.core.filter.steps import (
    AT_DETECTION,
    AT_OBS,
    AT_OUTCOMES,
    AT_PIECE,
    AT_PREDICTIONS,
    AT_ROW,
    Linearization,
)
from ekfslam.core.filter_checks import check_predict, check_predict_many, check_update
from ekfslam.core.initialisation import Held, triangulated
from ekfslam.core.models import MIN_RANGE_SQUARED

Array = NDArray[np.float64]

_NO_ROWS = np.zeros((0, len(ROW)))  # where a prediction records nothing
_NO_TAPE = (_NO_ROWS, np.zeros(0, dtype=np.int8), np.zeros((0, len(OBS_ROW))))  # a `Tape`
_OUTCOME = tuple(Outcome)  # _OUTCOME[code] is Outcome(code), at a tenth of the cost
_ACCEPTED = int(Outcome.ACCEPTED)
_ACCEPTED_OUTCOME = Outcome.ACCEPTED  # read as a global: a tenth of the enum's lookup
#: outcomes the correction did not compute (`EKFSLAM._finish`)
_PLACED_OR_NOT = (Outcome.INITIALISED, Outcome.REINITIALISED, Outcome.REFUSED, Outcome.DEFERRED)


def _rows(values: ArrayLike, width: int | None = None) -> Array:
    """Values as a C-ordered float array, (K,) or (K, width): the steps' one signature."""
    a = np.ascontiguousarray(values, dtype=float)
    return a if width is None else a.reshape(-1, width)


def _contiguous(values: ArrayLike) -> Array:
    """Values as a C-ordered float array, as they are when they are one already (`_rows`)."""
    return np.ascontiguousarray(values, dtype=float)


#: each outcome's `Outcome.label`, looked up once per sighting
_LABEL = {outcome: outcome.label for outcome in Outcome}


class Pieces(NamedTuple):
    """A run's K prediction pieces (`EKFSLAM.feed`): u (K, 3) body-frame increments, dt (K,)
    s, t (K,) s the time each ends, and the noise as `predict_many` takes it: M (3, 3) per
    second, or R (3, 3) per step (the other None)."""

    u: Array
    dt: Array
    t: Array
    M: Array | None
    R: Array | None


class Detections(NamedTuple):
    """A run's D detections in time order (`EKFSLAM.feed`): upto (D,) int64, the pieces that
    end by each; landmark_id (D,) int64; z (D, 2) range and bearing; Q (D, 2, 2) each one's
    noise; t (D,) s."""

    upto: NDArray[np.int64]
    landmark_id: NDArray[np.int64]
    z: Array
    Q: Array
    t: Array


class Rows(NamedTuple):
    """Where one observation is recorded: its event row (`ROW`), its observation row
    (`OBS_ROW`) and the event's index in the history (-1: scratch rows, nothing kept)."""

    row: Array
    obs: Array
    event: int


def _matrix(values: ArrayLike, n: int, what: str) -> Array:
    a = np.ascontiguousarray(values, dtype=float)
    if a.shape != (n, n):
        raise ValueError(f"{what} must be {n}x{n}, got shape {a.shape}")
    return a


class EKFSLAM(FilterState):
    """Landmark EKF SLAM with a growing state.

    The parameters are `FilterState`'s: the initial pose μ0 of eq. (1), its covariance Σ0 of
    eq. (2) (zero, a known start, by default), the `FilterConfig`, and whether to record a
    `History`.
    """

    def __init__(
        self,
        pose: ArrayLike,
        pose_covariance: ArrayLike | None = None,
        config: FilterConfig | None = None,
        record: bool = True,
    ) -> None:
        super().__init__(pose, pose_covariance, config, record)
        self._sightings: list[int] = []  # per slot: accepted sightings (gate, re-initialisation)
        self._rejected: list[list[Array]] = []  # per slot: where the rejected sightings put it
        self._t = 0.0
        self._linearisations = 1  # the iterated update's last count (`steps.linearise`)
        self._scratch = np.full(obs_width(self.sensor.size), math.nan)  # a row nobody keeps
        self._held = Clones()  # a two-sighting sensor's first sightings, their poses cloned
        self._control, self._size = self.motion.control_size, self.sensor.size
        self._event = np.zeros(len(ROW))  # an event row nobody keeps
        self._fej = self._storage.linearization == Linearization.FEJ  # H at first estimates
        self._cache_config()

    def _cache_config(self) -> None:
        """What `update`'s commonest path reads of the config, read once: whether a sighting
        of a mapped landmark takes it (one linearisation), and the gate."""
        self._plain = self.config.iterations == 1
        self._gate = math.inf if self.config.gate is None else float(self.config.gate)
        self._gate_after = self.config.gate_after
        self._no_rows = (self._event, self._scratch, -1)

    def clone(self) -> EKFSLAM:
        """`FilterState.clone`, with the filter's own lists (sightings, rejections)."""
        c = super().clone()
        c._sightings = list(self._sightings)
        c._rejected = [list(r) for r in self._rejected]
        c._scratch, c._event = self._scratch.copy(), self._event.copy()
        c._held = self._held.copy()
        c._cache_config()
        return c

    # ------------------------------------------------------------- prediction
    def predict(
        self, u: ArrayLike, R: ArrayLike, t: float | None = None, *, dt: float = 0.0
    ) -> None:
        """Move the pose by the control u, eqs. (6), (7) and (9).

        Parameters
        ----------
        u : array (k,)
            The control, k the motion model's `control_size`: the seed's body-frame increment
            (Δux, Δuy, Δθ) in m, m, rad, eq. (4).
        R : array (3, 3)
            Motion noise covariance in the state (x, y, θ) for this step; see
            `ekfslam.core.models.motion_noise` to build it from a control-noise covariance.
        t : float, optional
            Time after the step, s, for the history.
        dt : float, s
            The step's duration, which a motion model of rates integrates over (a unicycle's
            (v, ω)); the seed's increments do not read it.

        Only the pose block and the pose-landmark cross blocks change:
        Σ_rr <- G Σ_rr Gᵀ + R and Σ_rm <- G Σ_rm, which is eq. (9) with its lifts done right.
        """
        check_predict(u, R, t, self._control, dt)
        ts = np.array([self._t if t is None else float(t)])
        step = np.array([float(dt)])
        self._propagate((_rows(u, self._control), step, ts, _rows(R), False))  # R checked

    def predict_many(
        self,
        us: ArrayLike,
        dts: ArrayLike,
        ts: ArrayLike,
        M: ArrayLike | None = None,
        R: ArrayLike | None = None,
        *,
        validate: bool = True,
    ) -> None:
        """Several predictions in a row, exactly as many calls to `predict`, at O(n) once.

        The landmarks do not move, so the pose-landmark cross-covariance needs one update for
        the whole batch, by the product of its motion Jacobians, while the 3x3 pose block is
        stepped one increment at a time (`ekfslam.core.filter.steps.predict`).

        Parameters
        ----------
        us : (K, k) controls, k the motion model's `control_size` (the seed's increments
            (Δux, Δuy, Δθ)).
        dts : (K,) s, the duration of each step (scales M; a model of rates integrates over it).
        ts : (K,) s, the time after each step, for the history.
        M : (k, k), control covariance per second of driving: step k gets
            R_k = V (M dt_k) Vᵀ with V = F_v(pose, u_k, dt_k) (3, k)
            (`ekfslam.core.models.motion_noise`), at its start pose.
        R : (3, 3), or a fixed state-space R for every step (the seed's way). Give M or R.
        validate : check the arguments first (`ekfslam.core.filter_checks`) and take them as
            float arrays. False is for a caller whose arrays were checked already and are
            float64, C-ordered and of these shapes (a replay checks its run once, then feeds
            thousands of batches): as scipy's ``check_finite=False``, other input is then
            undefined behaviour.
        """
        per_second = M is not None
        N = M if per_second else R
        if validate and not check_predict_many(us, dts, ts, M, R, self._control):
            # not as the steps take them
            us, dts = _rows(us, self._control), _contiguous(dts)
            ts, N = _contiguous(ts), _contiguous(N)
        self._propagate((us, dts, ts, N, per_second))

    def _propagate(self, batch: tuple) -> None:
        """`ekfslam.core.filter.steps.predict` of a `Batch` (u, dt, t, N, per_second)."""
        rec, k = self._recorder, len(batch[0])
        rows = _NO_ROWS
        if rec is not None:
            r0 = rec.reserve(PREDICT, k)
            rows = rec.rows[r0 : r0 + k]
        if self._held.ids:  # a two-sighting sensor's held sightings: their poses' clones
            self._held.predict(self.motion, self._storage.mu[:3], batch)
        self._steps.predict(self._arrays, self._dim, batch, rows)
        self._counts["predictions"] += k
        if self._events + k >= self._look_at:
            self._ran(k)
        else:
            self._events += k
        if k:
            self._t = float(batch[2][-1])

    def feed(self, pieces: Pieces, detections: Detections) -> None:
        """A run's predictions and sightings in time order, exactly as `predict_many` through
        the pieces that end by each detection (`Detections.upto`), then `update` with it, and
        `predict_many` through the pieces after the last: a replay in one call.

        The run goes through `ekfslam.core.filter.steps.feed` (one compiled call for the lot,
        with the "numba" backend), which hands back to `update` each detection that needs a
        decision: a landmark seen for the first time, one whose last sightings were rejected,
        and a rejection when `FilterConfig.reinit_after` may place the landmark again. The
        arrays are taken as they are (float64 and int64, C-ordered, checked by the caller: as
        `predict_many`'s ``validate=False``). With `FilterConfig.iterations` > 1 every
        sighting goes back to `update` (the iterated update linearises in Python).
        """
        if self.sensor.g is None:
            raise ValueError(
                f"feed (and replay) take a sensor whose one sighting places a landmark; sensor "
                f"{self.sensor.name!r} needs two: feed it by predict_many and update"
            )
        u, dt, t, M, R = pieces
        per_second = M is not None
        batch = (u, dt, t, M if per_second else R, per_second)  # a `Batch`
        upto, ids, zs, Qs, times = detections
        iterated = self.config.iterations > 1  # every sighting back to `update`
        known, code = np.unique(ids, return_inverse=True)
        at = np.zeros(AT_OUTCOMES + len(Outcome), dtype=np.int64)
        clock = np.array([self._t])
        gate = math.inf if self.config.gate is None else float(self.config.gate)
        while True:
            rec = self._recorder
            if rec is not None:
                left = len(upto) - at[AT_DETECTION]  # detections, and pieces below
                rec.room(len(u) - at[AT_PIECE] + left, left)
                at[AT_ROW], at[AT_OBS] = rec.n, rec.m
            tape = (rec.rows, rec.kinds, rec.obs) if rec is not None else _NO_TAPE
            sightings = np.array(self._sightings, dtype=np.int64)
            slot_of = np.array([self.slot.get(int(i), -1) for i in known], dtype=np.int64)
            plan = (upto, ids, zs, Qs, times, code, slot_of, gate, self.config.gate_after)
            pending = np.array([iterated or bool(r) for r in self._rejected], dtype=np.bool_)
            plan += (sightings, pending)
            plan += (self.config.reinit_after is not None, clock)  # a `Plan`
            self._steps.feed(self._arrays, self._dim, batch, plan, tape, at)
            self._sightings = sightings.tolist()
            if rec is not None:
                rec.n, rec.m = int(at[AT_ROW]), int(at[AT_OBS])
            self._t = float(clock[0])
            i = int(at[AT_DETECTION])
            if i == len(upto):
                break
            self.update(int(ids[i]), zs[i], Qs[i], float(times[i]), validate=False)
            clock[0] = self._t
            at[AT_DETECTION] += 1
        self._counts["predictions"] += int(at[AT_PREDICTIONS])
        for outcome in Outcome:
            self._counts[outcome.label] += int(at[AT_OUTCOMES + outcome])

    # -------------------------------------------------------------- correction
    def update(
        self,
        landmark_id: int,
        z: ArrayLike,
        Q: ArrayLike,
        t: float | None = None,
        *,
        validate: bool = True,
    ) -> Outcome:
        """Use one observation z of a landmark (the seed's range and bearing), eqs. (10)-(16).

        A landmark seen for the first time is added to the state (eq. 12, see `FilterConfig.init`);
        with a sensor that needs two sightings (a bearing alone), the first is held (DEFERRED)
        and the landmark placed at a later one with enough parallax
        (`ekfslam.core.initialisation`, `FilterConfig.min_parallax`).
        Otherwise the innovation ν = z - ẑ (eq. 13, bearing wrapped) is gated on its NIS, and
        accepted ones update the state with the gain of eq. (15).

        Parameters
        ----------
        landmark_id : int
        z : array (m,)  the measurement, m the sensor's `SensorModel.size`: the seed's range
            (m) and bearing (rad).
        Q : array (m, m)  observation noise covariance, eq. (11).
        t : float, optional  time of the observation, s.
        validate : check the arguments first (as `predict_many`'s).

        Returns
        -------
        Outcome
            INITIALISED, ACCEPTED, REJECTED (failed the gate), REINITIALISED (see
            `FilterConfig.reinit_after`), REFUSED (cannot be linearised: the landmark, or
            the observation, sits on the robot) or SINGULAR (the innovation covariance S is
            singular or not finite: the noise is too small or too large). Each is counted
            (`counts`, under its `Outcome.label`).
        """
        if not (validate and check_update(landmark_id, z, Q, t, self._size)):
            z, Q = _contiguous(z), _contiguous(Q)  # not (known to be) as the steps take them
        if t is not None:
            self._t = float(t)
        self._events += 1
        if self._events >= self._look_at:
            self._ran(0)
        row, obs, event = self._no_rows if self._recorder is None else self._rows_to_record()
        j = self.slot.get(landmark_id)
        if j is not None and self._plain and not self._held.ids:  # the commonest case, in as few
            seen = self._sightings[j]  # Python steps as it takes
            gate = self._gate if seen >= self._gate_after else math.inf
            sighting = (self._t, int(landmark_id), z, Q, gate, event)  # a `Sighting`
            code = self._steps.sight(self._arrays, self._dim, 3 + 2 * j, sighting, row, obs)
            if code == _ACCEPTED:
                self._sightings[j] = seen + 1
                if self._rejected[j]:
                    self._rejected[j].clear()
                self._counts["accepted"] += 1
                return _ACCEPTED_OUTCOME
            return self._decide(landmark_id, j, z, Q, Rows(row, obs, event), _OUTCOME[code])
        rows = Rows(row, obs, event)
        if j is None and self.sensor.g is None:
            return self._triangulate(landmark_id, z, Q, rows)
        if j is None:
            if z[0] * z[0] <= MIN_RANGE_SQUARED:
                return self._finish(landmark_id, z, Outcome.REFUSED, -1, rows)
            j = self._add_landmark(landmark_id, z, Q)
            if self.config.init == "inverse":
                return self._finish(landmark_id, z, Outcome.INITIALISED, 3 + 2 * j, rows)
            return self._correct(landmark_id, j, z, Q, rows, accepted_as=Outcome.INITIALISED)
        gated = self.config.gate is not None and self._sightings[j] >= self.config.gate_after
        return self._correct(landmark_id, j, z, Q, rows, gate=self.config.gate if gated else None)

    def _rows_to_record(self) -> tuple[Array, Array, int]:
        """Where the observation being made is recorded, as a `Rows` (a plain tuple: the
        commonest path reads it by position): the history's event row (`ROW`), its observation
        row (`OBS_ROW`) and the event's index."""
        rec = self._recorder
        n = rec.reserve(OBSERVE, 1)
        m = rec.reserve_observation()  # may grow rec.obs: index the array it leaves
        return rec.rows[n], rec.obs[m], n

    def _point(self, l: int) -> Array:
        """Where H is evaluated for the landmark at rows l, l+1 (`steps.linearisation_point`)."""
        return self._steps.linearisation_point(self._arrays, l)

    def _correct(
        self,
        landmark_id: int,
        j: int,
        z: Array,
        Q: Array,
        rows: Rows,
        *,
        gate: float | None = None,
        accepted_as: Outcome = Outcome.ACCEPTED,
    ) -> Outcome:
        """The correction (`steps.sight`, which records it too; or the iterated update's), then
        the bookkeeping of its outcome."""
        l, s, gate = 3 + 2 * j, self._arrays, math.inf if gate is None else float(gate)
        if self.config.iterations > 1:
            outcome = self._correct_iterated(l, z, Q, gate, rows.obs)
        else:
            held = self._held
            if held.ids:  # the clones are corrected with the state (`ekfslam.core.filter.delayed`)
                before = held.before_correction(self.sensor, *s[:2], self._dim, l, z, Q)
            sighting = (self._t, int(landmark_id), z, Q, gate, rows.event)  # a `Sighting`
            outcome = _OUTCOME[self._steps.sight(s, self._dim, l, sighting, rows.row, rows.obs)]
            if held.ids and outcome == Outcome.ACCEPTED:
                held.corrected(before)
        return self._decide(landmark_id, j, z, Q, rows, outcome, accepted_as)

    def _decide(
        self,
        landmark_id: int,
        j: int,
        z: Array,
        Q: Array,
        rows: Rows,
        outcome: Outcome,
        accepted_as: Outcome = Outcome.ACCEPTED,
    ) -> Outcome:
        """The bookkeeping of a correction's outcome: re-placing the landmark after rejections,
        the accepted sightings, the count."""
        l = 3 + 2 * j
        if outcome == Outcome.REJECTED and self._should_reinitialise(j, z):
            return self._reinitialise(landmark_id, j, z, Q, rows)
        if outcome == Outcome.ACCEPTED:
            outcome = accepted_as
            if accepted_as == Outcome.ACCEPTED:
                self._sightings[j] += 1
            self._rejected[j].clear()
        if self.config.iterations > 1:
            return self._finish(landmark_id, z, outcome, l, rows)
        rows.obs[OBS_OUTCOME] = outcome  # `sight` recorded ACCEPTED for an `accepted_as`
        self._counts[_LABEL[outcome]] += 1
        return outcome

    def _correct_iterated(self, l: int, z: Array, Q: Array, gate: float, obs: Array) -> Outcome:
        """The iterated update (`iterated.linearise`, then `steps.correct` at its point)."""
        s = self._arrays
        update = (z, Q, gate, self._point(l))  # an `Update`
        taken = self._steps.linearise(s, self._dim, l, update, self.config.iterations, obs)
        target = obs
        if not np.isnan(taken[0]):  # the history keeps the first linearisation's ν, S
            update = (taken[5:-1].copy(), Q, math.inf, taken[:5].copy())
            target, self._linearisations = self._scratch, int(taken[-1])
        return _OUTCOME[self._steps.correct(s, self._dim, l, update, target)]

    def _add_landmark(self, landmark_id: int, z: Array, Q: Array, placement=None) -> int | None:
        """Append a landmark slot, eq. (12) for the mean; covariance by `config.init`; or where
        its two sightings put it (`ekfslam.core.initialisation.Placement`, its first sighting's
        clone marginalised: `ekfslam.core.filter.delayed.Clones.place`; None: too spread to
        place yet, nothing changed)."""
        j = len(self._ids)
        if self._dim + 2 > self._storage.mu.shape[0]:
            self._grow()
        if placement is None:
            self._dim += 2
            self._place(j, z, Q)
        else:
            d, s = self._dim, self._storage
            spread = self.config.max_spread
            rows = self._held.place(landmark_id, placement, s.Sigma, d, s.mu[:3], spread)
            if rows is None:  # too wide to place yet: held on
                return None
            self._dim += 2
            self._steps.set_landmark(self._arrays, self._dim, d, placement.landmark, rows)
        self._ids.append(landmark_id)
        self.slot[landmark_id] = j
        self._sightings.append(1)
        self._rejected.append([])
        return j

    def _place(self, j: int, z: Array, Q: Array) -> None:
        """Set slot j from one sighting as if first seen now (`steps.place_landmark`)."""
        seed = self.config.seed_init_variance if self.config.init == "seed" else 0.0
        update = (z, Q, math.inf, self._point(3 + 2 * j))  # an `Update`
        self._steps.place_landmark(self._arrays, self._dim, 3 + 2 * j, update, seed)

    def _triangulate(self, landmark_id: int, z: Array, Q: Array, rows: Rows) -> Outcome:
        """A sighting of a landmark not mapped yet by a sensor that needs two: held (DEFERRED,
        the pose cloned) if it is the first, or if it and the one held do not place the landmark
        (too little parallax: the first is kept; sightings that disagree: this one is held
        instead), else the landmark placed by both (`ekfslam.core.initialisation`)."""
        s = self._storage
        held = self._held.held(landmark_id)
        if held is not None:
            later = Held(s.mu[:3].copy(), z, Q)
            placement, keep = triangulated(self.sensor, held, later, self.config.min_parallax)
            if placement is not None:
                j = self._add_landmark(landmark_id, z, Q, placement)
                if j is None:
                    return self._finish(landmark_id, z, Outcome.DEFERRED, -1, rows)
                return self._finish(landmark_id, z, Outcome.INITIALISED, 3 + 2 * j, rows)
        if held is None or not keep:
            self._held.hold(landmark_id, z, Q, s.mu, s.Sigma, self._dim)
        return self._finish(landmark_id, z, Outcome.DEFERRED, -1, rows)

    def _should_reinitialise(self, j: int, z: Array) -> bool:
        """Have the landmark's last sightings, all rejected, agreed on a new place?

        How many: `reinit_after`, or as many as the sightings it has accepted, if more. A
        landmark placed by one bad sighting is re-placed quickly; one that many sightings
        confirmed is not re-placed by a short run of rejections, which on a long loop means
        the estimate has drifted (re-placing it would throw the loop closure away).
        """
        k = self.config.reinit_after
        if k is None:
            return False
        k = max(k, self._sightings[j])
        seen = self._rejected[j]
        seen.append(self.sensor.g(self._storage.mu[:3], z))
        if len(seen) < k:
            return False
        del seen[:-k]
        return _new_place(seen, self.mu[3:].reshape(-1, 2), j, self.config.reinit_radius)

    def _reinitialise(self, landmark_id: int, j: int, z: Array, Q: Array, rows: Rows) -> Outcome:
        self.settle()
        self._place(j, z, Q)
        self._sightings[j] = 1
        self._rejected[j].clear()
        if self.config.init == "seed":  # eq. (3), then the update with this sighting
            return self._correct(landmark_id, j, z, Q, rows, accepted_as=Outcome.REINITIALISED)
        return self._finish(landmark_id, z, Outcome.REINITIALISED, 3 + 2 * j, rows)

    def _finish(self, landmark_id: int, z: Array, outcome: Outcome, l: int, rows: Rows) -> Outcome:
        """Count the outcome and record the state after it (l < 0: the landmark has no slot).

        An outcome the correction did not compute (a landmark placed, or refused) records its
        ẑ, ν, S and NIS as NaN.
        """
        if outcome in _PLACED_OR_NOT and (l < 0 or self.config.init == "inverse"):
            rows.obs[:] = math.nan
        self._counts[_LABEL[outcome]] += 1
        observed = (self._t, int(landmark_id), z, int(outcome), rows.event)  # an `Observed`
        self._steps.record_observation(self._arrays, self._dim, l, observed, rows.row, rows.obs)
        return outcome

    # ---------------------------------------------------------- for the association
    def predictions(self, zs: Array, Q: Array, rate: Rate | None = None) -> Predicted:
        """ν (m, n, 2), P = H Σ Hᵀ (2n, 2n) and the NIS (m, n) of the sightings zs (m, 2) of one
        time against every mapped landmark (`ekfslam.core.filter.predictions.predict_all`);
        with a `Rate`, P holds the image's shared time-stamp term too."""
        self.settle()  # the invariant filter's owed heading noise, before Σ is read
        return predictions_of(self._steps, self._arrays, self._dim, zs, Q, rate)

    def nearest(self, zs: Array, Q: Array, gate: float) -> tuple[list[int], list[float]]:
        """Each sighting's landmark slot of smallest NIS within the gate (-1: none), and that
        smallest NIS (`ekfslam.core.filter.predictions.nearest`, O(m n))."""
        self.settle()
        return nearest_of(self._steps, self._arrays, self._dim, zs, Q, gate)

    def accepted_sightings(self) -> tuple[int, ...]:
        """How many sightings each landmark has accepted, in slot order (its placing counts)."""
        return tuple(self._sightings)

    def start_with_map(self, means: ArrayLike, covariance: ArrayLike, sightings) -> None:
        """Put a known map into a filter that has taken no step (`ekfslam.core.filter.prior`):
        landmark j gets slot j and id j, the means (n, 2), their joint covariance (2n, 2n) and
        no correlation with the pose, whose Σ0 stays the filter's own; sightings (n,) the
        accepted sightings each had (the re-initialisation rule weighs rejections by them)."""
        if self.n_landmarks or self.counts.predictions:
            raise ValueError("a prior map goes into a filter that has taken no step")
        if self._invariant:
            raise ValueError("a prior map needs the standard or FEJ filter (not 'invariant')")
        means = np.asarray(means, dtype=float).reshape(-1, 2)
        n = len(means)
        while 3 + 2 * n > self._storage.mu.shape[0]:
            self._grow()
        s, m = self._storage, slice(3, 3 + 2 * n)
        self._dim = 3 + 2 * n
        s.mu[m] = s.first[m] = means.ravel()
        s.Sigma[:3, m] = s.Sigma[m, :3] = 0.0
        s.Sigma[m, m] = np.asarray(covariance, dtype=float)
        for j in range(n):
            self._ids.append(j)
            self.slot[j] = j
            self._sightings.append(int(sightings[j]))
            self._rejected.append([])


def _new_place(seen: list, landmarks: Array, j: int, radius: float) -> bool:
    """Do the rejected sightings `seen` (k, 2) agree on one place that no other landmark holds?"""
    seen = np.asarray(seen)
    centre = seen.mean(axis=0)
    if np.max(np.hypot(*(seen - centre).T)) > radius:
        return False
    others = np.delete(landmarks, j, axis=0)
    return not np.any(np.hypot(*(others - centre).T) <= radius)
