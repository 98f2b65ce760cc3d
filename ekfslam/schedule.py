"""A run as the filter takes it, and the loops that feed it.

`schedule` turns a `ekfslam.logs.runlog.RunLog` into a `Schedule`: every control interval split
at the detections inside it (each control row held until the next), the detections in time
order, and the noise they are fed with. `feed` gives a filter the schedule with the ids known
(`ekfslam.core.filter.ekf.EKFSLAM.feed`, one call, or step by step when something watches each
update); `feed_hidden` gives it the sightings of each time together, for an association to
decide. `KeyframeTaker` copies the whole state at evenly spread moments while a feed runs.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.filter.associating import AssociatingFilter
from ekfslam.core.filter.ekf import EKFSLAM, Detections, Pieces
from ekfslam.core.filter.history import KeyframeRecorder, Keyframes
from ekfslam.core.filter.mapping import MappingFilter
from ekfslam.core.filter.mht import HypothesisBank
from ekfslam.core.noise import NoiseConfig
from ekfslam.core.recovery import Recovery
from ekfslam.errors import EkfSlamError
from ekfslam.logs.runlog import RunLog

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Schedule:
    """A run as the filter takes it: the prediction pieces and the detections, in time order.

    The pieces are every control interval, split at the detection times inside it (each control
    row held until the next): u (K, 3) the body-frame increments of eq. (4), dt (K,) s, t (K,)
    s the time each ends. Before detection i the filter predicts through the pieces up to
    upto[i]. The detections: ids (N,), times (N,) s, z (N, 2) range and bearing. The noise
    they are fed with: M (3, 3) per second, or R (3, 3) per step (the other None), and Q:
    (2, 2) for every detection, or (N, 2, 2) each its own (`noise_of`); the `NoiseConfig` they
    came from.
    """

    upto: list[int]
    u: Array
    dt: Array
    t: Array
    ids: list[int]
    times: list[float]
    z: list[list[float]]
    M: Array | None
    R: Array | None
    Q: Array
    noise: NoiseConfig | None = None

    def with_noise(self, noise: NoiseConfig) -> Schedule:
        """The same schedule with another noise's M, R (eq. 9) and Q (eq. 11)."""
        fixed = None if noise.R_per_step is None else np.asarray(noise.R_per_step, dtype=float)
        M = noise.motion_density() if fixed is None else None
        return dataclasses.replace(self, M=M, R=fixed, Q=noise.Q, noise=noise)

    def noise_of(self, i: int) -> Array:
        """Q (2, 2) of detection i: the one Q, or its own when Q holds one per detection."""
        return self.Q if self.Q.ndim == 2 else self.Q[i]

    def predict(self, target, start: int, stop: int, **options) -> None:
        """Predict `target` through pieces start..stop-1 (`EKFSLAM.predict_many`, with
        `options`)."""
        target.predict_many(
            self.u[start:stop], self.dt[start:stop], self.t[start:stop], self.M, self.R, **options
        )

    def pieces(self) -> Pieces:
        """The prediction pieces as `EKFSLAM.feed` takes them."""
        return Pieces(self.u, self.dt, self.t, self.M, self.R)

    def detections(self) -> Detections:
        """The detections as `EKFSLAM.feed` takes them (arrays; Q one per detection)."""
        n = len(self.ids)
        Q = self.Q if self.Q.ndim == 3 else np.broadcast_to(self.Q, (n, 2, 2))
        return Detections(
            upto=np.array(self.upto, dtype=np.int64),
            landmark_id=np.array(self.ids, dtype=np.int64),
            z=np.array(self.z, dtype=float).reshape(n, 2),
            Q=np.ascontiguousarray(Q, dtype=float),
            t=np.array(self.times, dtype=float),
        )

    @property
    def events(self) -> int:
        """Predictions and detections: what the filter will be fed."""
        return len(self.u) + len(self.ids)


def schedule(run: RunLog, noise: NoiseConfig) -> Schedule:
    """The run's `Schedule` with this noise."""
    twist = run.control_twist()
    if len(twist) == 0:
        raise ValueError(f"run {run.meta.name!r} has no controls")
    t_ctrl = np.asarray(run.controls.t, dtype=float)
    det = run.detections
    det_t = np.asarray(det.t, dtype=float)
    t_first = min(t_ctrl[0], det_t[0]) if len(det_t) else t_ctrl[0]
    t_end = max(t_ctrl[-1], det_t[-1]) if len(det_t) else t_ctrl[-1]
    cuts = np.unique(np.concatenate([t_ctrl, det_t, [t_first, t_end]]))
    starts, ends = cuts[:-1], cuts[1:]
    row = np.searchsorted(t_ctrl, starts, side="right") - 1  # the control row in force
    moving = row >= 0  # before the first control the robot stands still
    starts, ends, row = starts[moving], ends[moving], row[moving]
    dts = ends - starts
    us = twist[row] * dts[:, None]
    upto = np.searchsorted(ends, det_t, side="right")  # the pieces that end by detection i
    return Schedule(
        upto=upto.tolist(),
        u=np.ascontiguousarray(us, dtype=float),
        dt=np.ascontiguousarray(dts, dtype=float),
        t=np.ascontiguousarray(ends, dtype=float),
        ids=det.tag_id.tolist(),
        times=det_t.tolist(),
        z=np.column_stack([det.range, det.bearing]).tolist(),
        M=None,
        R=None,
        Q=np.zeros((2, 2)),
    ).with_noise(noise)


class KeyframeTaker:
    """`feed`'s pause: copies the state when the number of detections used reaches each target.

    Targets: `count` - 1 numbers of detections evenly spread over 0..N (0 is the start, N the
    state after the last detection), then the end of the run in `finish`. With hidden ids the
    pause comes only between one time's sightings, so a target inside a group waits for its end.
    """

    def __init__(self, ekf: EKFSLAM, steps: Schedule, count: int) -> None:
        dts, ends, det_time = steps.dt, steps.t, steps.times
        self.det_time = det_time
        n = len(det_time)
        self.targets = np.unique(np.round(np.linspace(0, n, count - 1)).astype(int)).tolist()
        self.ekf, self.next = ekf, 0
        self.t_start = float(ends[0] - dts[0]) if len(ends) else 0.0
        self.t_end = float(ends[-1]) if len(ends) else self.t_start
        self.recorder = KeyframeRecorder()

    def pause(self, i: int, done: int) -> None:
        if self.next < len(self.targets) and self.targets[self.next] <= i:
            while self.next < len(self.targets) and self.targets[self.next] <= i:
                self.next += 1
            t = self.t_start if i == 0 else max(self.t_start, self.det_time[i - 1])
            self.recorder.take(t, i, self.ekf.mu, self.ekf.Sigma)

    def finish(self) -> Keyframes:
        ekf = self.ekf
        t_last = self.det_time[-1] if len(self.det_time) else self.t_start
        self.recorder.take(max(self.t_end, t_last), len(self.det_time), ekf.mu, ekf.Sigma)
        return self.recorder.finish(ekf.landmark_ids)


class NonFiniteStateError(EkfSlamError):
    """The filter's mean or covariance became NaN or infinite; the message says where."""


def feed(ekf: EKFSLAM | Recovery, steps: Schedule, *, check: bool = False, pause=None) -> None:
    """Predict through the pieces before each detection, update, and predict to the end: the
    filter's `EKFSLAM.feed`, in one call, or step by step when a `Recovery` watches each update,
    or when `check` or `pause` asks to stop between them.

    check: after every step, raise `NonFiniteStateError` naming the step if the state is no
    longer finite (the locating pass; the normal pass checks once, at the end).
    pause: called as pause(i, done) when detections 0..i-1 are applied and `done` pieces
    predicted, before the prediction for detection i (i = len(upto): before the last one).
    """
    if pause is None and not check and isinstance(ekf, EKFSLAM):  # (not a `Recovery`'s watch)
        ekf.feed(steps.pieces(), steps.detections())
        return
    done = 0
    for i, p in enumerate(steps.upto):
        if pause is not None:
            pause(i, done)
        if p > done:
            steps.predict(ekf, done, p, validate=False)  # the run was checked once, when read
            done = p
            if check:
                check_finite(ekf, f"t = {steps.t[p - 1]:.3f} s (prediction)")
        ekf.update(steps.ids[i], steps.z[i], steps.noise_of(i), steps.times[i], validate=False)
        if check:
            where = f"update of landmark {steps.ids[i]}, detection {i + 1}"
            check_finite(ekf, f"t = {steps.times[i]:.3f} s ({where})")
    if pause is not None:
        pause(len(steps.upto), done)
    if done < len(steps.u):
        steps.predict(ekf, done, len(steps.u), validate=False)
        if check:
            check_finite(ekf, f"t = {steps.t[-1]:.3f} s (prediction to the end)")


def feed_hidden(
    associating: AssociatingFilter | HypothesisBank | MappingFilter,  # (DecisionReplay is one)
    steps: Schedule,
    *,
    pause=None,
) -> None:
    """`feed` without the ids: the detections of one time are associated together.

    The ids are not looked at (the filter must not know them); the replay's pieces are the same.
    associating: an `AssociatingFilter`; a `HypothesisBank` (``mht``), which keeps no history;
    or what replays decisions already made (`DecisionReplay`, `MappingFilter`).
    pause: as `feed`'s, called only between one time's sightings and the next.
    """
    done = 0
    for i, k in one_time_groups(steps.times):
        if pause is not None:
            pause(i, done)
        p = steps.upto[i]
        if p > done:
            steps.predict(associating, done, p, validate=False)  # the run was checked once
            done = p
        associating.observe(steps.z[i:k], steps.Q, steps.times[i], *body_rate(steps, p))
    if pause is not None:
        pause(len(steps.upto), done)
    if done < len(steps.u):
        steps.predict(associating, done, len(steps.u), validate=False)


def one_time_groups(det_time) -> Iterator[tuple[int, int]]:
    """(i, k) for each run of detections i..k-1 taken at one time (one image's sightings)."""
    i, n = 0, len(det_time)
    while i < n:
        k = i + 1
        while k < n and det_time[k] == det_time[i]:
            k += 1
        yield i, k
        i = k


def body_rate(steps: Schedule, p: int) -> tuple[float, tuple[float, float]]:
    """rad/s and the body velocity (m/s) of the piece that ends at the sightings (a time-stamp
    error moves the pose they were taken from)."""
    if p > 0 and steps.dt[p - 1] > 0:
        vx, vy, w = (steps.u[p - 1] / steps.dt[p - 1]).tolist()
        return w, (vx, vy)
    return 0.0, (0.0, 0.0)


def check_finite(ekf: EKFSLAM, where: str) -> None:
    if not (np.isfinite(ekf.mu).all() and np.isfinite(ekf.Sigma).all()):
        raise NonFiniteStateError(
            f"the filter state became non-finite at {where}: check the noise settings and the "
            "log's values near that time"
        )
