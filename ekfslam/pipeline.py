"""Replay a run log through the filter in time order.

Controls and detections are merged by timestamp: before each detection the pose is predicted up to
the detection's time (each control row held until the next row, so a control interval is split at
the detections inside it), then the detection corrects the state. After the last detection the
prediction runs on to the end of the controls.

The filter never learns where the data came from: a simulated run, a CSV log, MRCLAM or camera
frames all arrive here as a `ekfslam.logs.runlog.RunLog`.
"""

from __future__ import annotations

import copy
import dataclasses
import time
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam import checks
from ekfslam.core.association import AssociationConfig
from ekfslam.core.diagnosis import Diagnosis, diagnose
from ekfslam.core.filter.associating import AssociatingFilter, AssociationLog, shares_image_error
from ekfslam.core.filter.config import MAX_PASSES, FilterConfig, FilterCounts, backend_for
from ekfslam.core.filter.ekf import EKFSLAM, Detections, Pieces
from ekfslam.core.filter.history import History, KeyframeRecorder, Keyframes
from ekfslam.core.filter.mapping import MappingFilter
from ekfslam.core.filter.mht import DecisionReplay, HypothesisBank
from ekfslam.core.filter.prior import PassRecord, pass_record, prior_map, start_with
from ekfslam.core.noise import NoiseConfig, default_config, default_noise, sighting_noise
from ekfslam.core.recovery import Recovery, RecoveryConfig
from ekfslam.errors import ConfigError, EkfSlamError
from ekfslam.logs.edit import truncate
from ekfslam.logs.runlog import RunLog, check_replayable
from ekfslam.plausibility import MAX_HEADING, MAX_POSITION

Array = NDArray[np.float64]

#: What one event costs the steps run as Python, against a replay with the ids known, by the
#: association (its work at each time runs in those steps too; ``mht``'s is per hypothesis):
#: the octagon replayed with each, ``FilterConfig(backend="python")``, 2026-12-06: known 88 ms,
#: nn 177 ms, jcbb 403 ms, mht with 8 hypotheses 4,071 ms. `replay` weighs a run's events by it
#: to choose backend "auto" (`backend_for`): an mht replay of a short run is a long one.
PYTHON_COST = {"known": 1, "nn": 2, "jcbb": 5, "mht": 6}

#: The most keyframes `replay` keeps: each is a copy of the whole state (μ and Σ).
MAX_KEYFRAMES = 100_000


@dataclass(frozen=True, eq=False)
class ReplayResult:
    """What a replay produced.

    name : the run's name.
    landmarks : {id: mean (2,)} the estimated map; landmark_covariances {id: (2, 2)}.
    mu, Sigma : the final state (3 + 2n,) and covariance; the only n x n object kept.
    history : every event (see `ekfslam.core.filter.history.History`).
    counts : predictions, initialised, accepted, rejected, refused.
    seconds : wall time of the replay loop.
    association : with ids hidden (``nn``, ``jcbb``, ``mht``), every sighting's decision, in the
        order of ``run.detections``; the landmarks are then keyed by estimated id. None for
        ``known``.
    keyframes : the full state at evenly spread moments, when `replay` was asked for them.
    map_noise : the mapping filter's noise when the decisions were replayed through one
        (`replay`'s ``map_noise``); the state, history and counts are then its. `noise` is the
        deciding filter's.
    passes, chosen_pass : with `replay`'s ``passes`` > 1, each pass's record
        (`ekfslam.core.filter.prior.PassRecord`) and which one (1, 2, ...) the result is;
        () and 1 for a single pass.
    diagnosis : does the filter agree with its data (`ekfslam.core.diagnosis.Diagnosis`): the
        verdict "ok", "suspect" or "lost" and the figures behind it, from `history`.
    """

    name: str
    landmarks: dict[int, Array]
    landmark_covariances: dict[int, Array]
    mu: Array
    Sigma: Array
    history: History
    counts: FilterCounts
    seconds: float
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    config: FilterConfig = field(default_factory=FilterConfig)
    association: AssociationLog | None = None
    keyframes: Keyframes | None = None
    map_noise: NoiseConfig | None = None
    passes: tuple[PassRecord, ...] = ()
    chosen_pass: int = 1
    diagnosis: Diagnosis | None = None


def replay(
    run: RunLog,
    noise: NoiseConfig | None = None,
    config: FilterConfig | None = None,
    *,
    start_pose: ArrayLike | None = None,
    start_covariance: ArrayLike | None = None,
    association: AssociationConfig | None = None,
    keyframes: int | None = None,
    map_noise: NoiseConfig | None = None,
    passes: int = 1,
    recovery: RecoveryConfig | None = None,
    replays: int = 1,
) -> ReplayResult:
    """Run the EKF over a log and return the estimate with its full history.

    Parameters
    ----------
    run : RunLog
    noise : NoiseConfig, the R and Q to use (default: `default_noise(run)`). With the ids known,
        each sighting gets its own Q when the run's detections carry their σ or the noise's σ_r
        grows with the range (`ekfslam.core.noise.sighting_noise`).
    config : FilterConfig, landmark initialisation, gate (default: `default_config(run)`).
    start_pose : (3,), where the filter starts; the run's nominal start by default (the seed
        starts from its nominal pose and recovers the placement error afterwards, eq. 17).
    start_covariance : (3, 3), Σ0 of eq. (2); zero by default (the seed's choice).
    association : how sightings are matched to landmarks (`ekfslam.core.association`); with
        ``known`` (the default) the detections' ids, else the ids are hidden from the filter and
        the sightings of each time are associated (`ekfslam.core.filter.associating`); with
        ``mht`` a bank of hypotheses decides (`ekfslam.core.filter.mht`), and the winner's
        decisions are then replayed through the filter to record its history.
    keyframes : how many copies of the full state (μ, Σ) to keep (`History` keeps only the pose
        block), at least 2: the start, the state after evenly spread numbers of detections, and
        the end; fewer when the run has fewer detections. None (the default) keeps none and
        costs nothing. An animation's frames (`ekfslam.viz.animation`).
    map_noise : with hidden ids, decide with `noise` and map with this: the decisions are fed
        as ids to a fresh filter with this noise (`ekfslam.core.filter.mapping.MappingFilter`),
        whose state, history and counts the result holds; the association log is the deciding
        run's. None (the default): one filter decides and maps.
    passes : with hidden ids, how many times to decide the whole run (offline: the run is read
        once per pass). Pass k + 1 decides every sighting again, its filter started with pass
        k's final map as prior knowledge (`ekfslam.core.filter.prior`); each pass's decisions
        are then mapped from scratch (by the mapping filter; without `map_noise` by a fresh
        filter with `noise`), so no sighting counts twice. The result is the pass whose map fits its
        sightings best (`ekfslam.core.filter.prior.pass_record`'s cost); it stops early at a
        fixed point (no decision changed). 1 (the default): one pass.
    recovery : with the ids known, widen the pose covariance after a run of rejected sightings
        (`ekfslam.core.recovery`), so a filter that has lost its pose relocalises against its
        map; the times are in ``result.diagnosis.recoveries``. None (the default): never.
    replays : how many replays like this one the caller makes in this process (a Monte Carlo,
        a noise fit, a sweep). With ``FilterConfig(backend="auto")`` their events together
        decide whether the compiled steps pay for their loading (`backend_for`): twenty replays
        of a short run are a long one. 1 (the default): this replay alone.
    """
    check_replayable(run, "replay: run")
    if not checks.is_whole(replays) or int(replays) < 1:
        raise ConfigError(
            f"replay: replays must be a whole number >= 1, got {checks.shown(replays)}"
        )
    for name, value, kind, hint in (
        ("noise", noise, NoiseConfig, "e.g. NoiseConfig(sigma_range=0.05)"),
        ("config", config, FilterConfig, "e.g. FilterConfig(gate=None)"),
        ("association", association, AssociationConfig, 'e.g. AssociationConfig(method="jcbb")'),
        ("map_noise", map_noise, NoiseConfig, "e.g. NoiseConfig(sigma_x=0.005)"),
    ):
        if value is not None:
            checks.instance(value, kind, f"replay: {name}", hint)
    if start_pose is not None:  # its plausibility below, with the run's nominal start's
        checks.array(start_pose, "replay: start_pose", (3,), "a pose (x, y, theta)", finite=False)
    if start_covariance is not None:
        checks.covariance(start_covariance, "replay: start_covariance", 3)
    whole = isinstance(keyframes, int | np.integer) and not isinstance(keyframes, bool)
    if keyframes is not None and not (whole and 2 <= keyframes <= MAX_KEYFRAMES):
        raise ConfigError(
            f"keyframes must be a whole number from 2 to {MAX_KEYFRAMES} (each is a copy of the "
            f"whole state), got {checks.shown(keyframes)}"
        )
    noise = noise or default_noise(run)
    config = config or default_config(run)
    pose0 = run.meta.nominal_start if start_pose is None else start_pose
    p = np.asarray(pose0, dtype=float)
    if p.shape != (3,) or not (np.all(np.abs(p[:2]) <= MAX_POSITION) and abs(p[2]) <= MAX_HEADING):
        # a finite 1e308 start overflows in the alignment: a table of NaN, not an error
        whose = "replay: start_pose" if start_pose is not None else "the run's nominal_start"
        raise ConfigError(
            f"{whose} {p.tolist()} is not a plausible (x, y, theta): |x|, |y| <= "
            f"{MAX_POSITION:g} m, |theta| <= 2 pi rad"
        )
    hidden = association is not None and association.method != "known"
    if map_noise is not None and not hidden:
        raise ConfigError("map_noise needs hidden ids (an association other than 'known')")
    if recovery is not None and hidden:
        raise ConfigError(
            "recovery needs the ids known (with hidden ids a run of rejections is "
            "also a question of association)"
        )
    _check_passes(passes, hidden, config)
    started = time.perf_counter()  # the schedule counts: it is part of the replay's work
    steps = schedule(run, noise)
    # "auto": compiled for long runs, many short ones, and an association's heavier work
    asked, config = (
        config,
        backend_for(config, _work(steps, association, passes, map_noise) * replays),
    )
    each = sighting_noise(noise, run.detections)
    if np.ndim(each) == 3 and not hidden:  # each sighting its own Q (the run's, or by range)
        steps = dataclasses.replace(steps, Q=each)
    elif np.ndim(each) == 3:
        warnings.warn(
            f"run {run.meta.name!r}: with hidden ids every sighting has sigma_range and "
            "sigma_bearing; its own noise (detections.csv's sigma columns, sigma_range_per_m) "
            "is used with the ids known only",
            RuntimeWarning,
            stacklevel=2,
        )
    kept: list = []  # the pass the result is: filter, log, keyframes, its record's index
    records: list[PassRecord] = []
    with np.errstate(all="ignore"):  # an overflow is caught below, once, and said where
        if not hidden:
            ekf = EKFSLAM(pose0, start_covariance, config)
            fed = ekf if recovery is None else Recovery(ekf, recovery)
            taker = None if keyframes is None else _KeyframeTaker(ekf, steps, int(keyframes))
            _feed(fed, steps, pause=None if taker is None else taker.pause)
            log = None
        else:
            made, prior, last = (pose0, start_covariance, config), None, None
            for k in range(passes):  # each pass decides again from the last one's map
                ekf, decider, log, taker = _hidden_pass(
                    made, association, steps, noise, map_noise, keyframes, prior
                )
                if passes == 1:
                    kept = [ekf, log, taker, k]
                    break
                records.append(pass_record(ekf.history(), config.gate, log.estimated, last))
                if not kept or records[-1].cost < records[kept[3]].cost:
                    kept = [ekf, log, taker, k]
                if records[-1].changed == 0:
                    break  # a fixed point: another pass would decide the same
                prior, last = prior_map(decider), log.estimated
            ekf, log, taker = kept[:3]
    seconds = time.perf_counter() - started
    frames = None if taker is None else taker.finish()
    if not hidden and not (np.isfinite(ekf.mu).all() and np.isfinite(ekf.Sigma).all()):
        # once per replay, O(n²); only on failure is the run fed again, checking every step
        with np.errstate(all="ignore"):
            _feed(EKFSLAM(pose0, start_covariance, config, record=False), steps, check=True)
        raise NonFiniteStateError(f"run {run.meta.name!r}: the filter state became non-finite")
    if ekf.counts.singular:
        warnings.warn(
            f"run {run.meta.name!r}: {ekf.counts.singular} updates skipped because the "
            "innovation covariance S was singular or not finite (is the noise too small or "
            "too large?)",
            RuntimeWarning,
            stacklevel=2,
        )
    if hidden and not (np.isfinite(ekf.mu).all() and np.isfinite(ekf.Sigma).all()):
        raise NonFiniteStateError(f"run {run.meta.name!r}: the filter state became non-finite")
    recovered = () if hidden or recovery is None else tuple(fed.times)
    result = _result(run, ekf, seconds, noise, asked, log, frames, map_noise, recovered)
    if passes == 1:
        return result
    return dataclasses.replace(result, passes=tuple(records), chosen_pass=kept[3] + 1)


def _work(
    steps: Schedule,
    association: AssociationConfig | None,
    passes: int,
    map_noise: NoiseConfig | None,
) -> int:
    """A replay's events weighed by what each costs the Python steps (`PYTHON_COST`): every
    hypothesis of ``mht``, every pass, and the mapping filter's replay of the decisions."""
    if association is None or association.method == "known":
        return steps.events
    cost = PYTHON_COST[association.method]
    if association.method == "mht":
        cost *= association.hypotheses
    return steps.events * cost * passes + (steps.events if map_noise is not None else 0)


def _check_passes(passes: object, hidden: bool, config: FilterConfig) -> None:
    """`replay`'s ``passes``: a whole number 1..`MAX_PASSES`; more than one needs hidden ids and
    a filter whose Σ is Cartesian (a prior map is given as one)."""
    whole = isinstance(passes, int | np.integer) and not isinstance(passes, bool)
    if not (whole and 1 <= passes <= MAX_PASSES):
        raise ConfigError(f"passes must be a whole number from 1 to {MAX_PASSES}, got {passes!r}")
    if passes > 1 and not hidden:
        raise ConfigError("passes > 1 needs hidden ids (an association other than 'known')")
    if passes > 1 and config.linearization == "invariant":
        raise ConfigError("passes > 1 needs the standard or FEJ filter, not 'invariant'")


def _hidden_pass(made, association, steps, noise, map_noise, keyframes, prior):
    """One pass with the ids hidden: decide every sighting (from `prior`'s map, if given) and,
    with `map_noise`, map the decisions with a fresh filter; with a prior too, with `noise` if
    no `map_noise` (the prior holds these sightings already: the map must not get them twice).
    Returns the filter whose state is the result (it records), the deciding filter, the
    decisions and the keyframe taker."""
    pose0, start_covariance, config = made
    ekf = EKFSLAM(pose0, start_covariance, config)
    mapped = map_noise is not None or prior is not None  # the mapping filter records
    decider = EKFSLAM(pose0, start_covariance, config, record=False) if mapped else ekf
    if prior is not None:
        start_with(decider, prior)
    taker = None if keyframes is None else _KeyframeTaker(ekf, steps, int(keyframes))
    pause = None if taker is None else taker.pause
    if association.method == "mht":  # the bank decides, a replay records
        first = EKFSLAM(pose0, start_covariance, config, record=False)
        bank = HypothesisBank(first if prior is None else start_with(first, prior), association)
        _feed_hidden(bank, steps)
        _, winner, options = bank.finish()
        associating = DecisionReplay(decider, association, winner, options)
    else:
        associating = AssociatingFilter(decider, association)
    _feed_hidden(associating, steps, pause=None if mapped else pause)
    log = associating.finish()
    if mapped:
        shared = shares_image_error(association)  # as it decided
        mapping = MappingFilter(ekf, log, association.time_sigma, shared)
        _feed_hidden(mapping, steps.with_noise(map_noise or noise), pause=pause)
        mapping.finish()
    return ekf, decider, log, taker


class _KeyframeTaker:
    """`_feed`'s pause: copies the state when the number of detections used reaches each target.

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


@dataclass(frozen=True, eq=False)
class Schedule:
    """A run as the filter takes it: the prediction pieces and the detections, in time order.

    The pieces are every control interval, split at the detection times inside it (each control
    row held until the next): u (K, 3) the body-frame increments of eq. (4), dt (K,) s, t (K,)
    s the time each ends. Before detection i the filter predicts through the pieces up to
    upto[i]. The detections: ids (N,), times (N,) s, z (N, 2) range and bearing. The noise
    they are fed with: M (3, 3) per second, or R (3, 3) per step (the other None), and Q:
    (2, 2) for every detection, or (N, 2, 2) each its own (`noise_of`).
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

    def with_noise(self, noise: NoiseConfig) -> Schedule:
        """The same schedule with another noise's M, R (eq. 9) and Q (eq. 11)."""
        fixed = None if noise.R_per_step is None else np.asarray(noise.R_per_step, dtype=float)
        M = noise.motion_density() if fixed is None else None
        return dataclasses.replace(self, M=M, R=fixed, Q=noise.Q)

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


def _result(
    run: RunLog,
    ekf: EKFSLAM,
    seconds: float,
    noise: NoiseConfig,
    config: FilterConfig,
    association: AssociationLog | None = None,
    keyframes: Keyframes | None = None,
    map_noise: NoiseConfig | None = None,
    recoveries: tuple[float, ...] = (),
) -> ReplayResult:
    ids = ekf.landmark_ids
    history = ekf.history()
    return ReplayResult(
        name=run.meta.name,
        landmarks=ekf.landmark_map(),
        landmark_covariances={i: ekf.landmark(i)[1] for i in ids},
        mu=ekf.mu.copy(),
        Sigma=ekf.Sigma.copy(),
        history=history,
        counts=ekf.counts,
        seconds=seconds,
        noise=noise,
        config=config,
        association=association,
        keyframes=keyframes,
        map_noise=map_noise,
        diagnosis=diagnose(history, recoveries, association),
    )


class NonFiniteStateError(EkfSlamError):
    """The filter's mean or covariance became NaN or infinite; the message says where."""


def replay_until(
    run: RunLog,
    t_end: float,
    noise: NoiseConfig | None = None,
    config: FilterConfig | None = None,
) -> ReplayResult:
    """Replay the run up to `t_end` (s): the filter's state, with its full Σ, at that time.

    Cut at a detection time, the result is exactly the full replay's state after that detection
    (the prediction pieces are the same); cut between detections, the last piece is split.
    """
    return replay(truncate(run, t_end), noise, config)


def replay_until_each(
    run: RunLog,
    times: Sequence[float],
    noise: NoiseConfig | None = None,
    config: FilterConfig | None = None,
) -> tuple[ReplayResult, tuple[ReplayResult, ...]]:
    """The full replay and, from the same pass, `replay_until(run, t)` for each t in `times`.

    One pass over the log instead of one per time: at the last detection before t the filter is
    copied and the copy predicted to t with the pieces `replay_until` would use, so each state
    equals `replay_until`'s bit for bit while the full replay's pieces stay unsplit.
    """
    noise = noise or default_noise(run)
    config = config or default_config(run)
    started = time.perf_counter()
    steps = schedule(run, noise)
    config = backend_for(config, steps.events)
    ekf = EKFSLAM(run.meta.nominal_start, None, config)
    waiting: dict[int, list[tuple[int, RunLog, Schedule]]] = {}
    for k, t in enumerate(times):
        cut = truncate(run, float(t))
        waiting.setdefault(len(cut.detections.t), []).append((k, cut, schedule(cut, noise)))
    found: dict[int, ReplayResult] = {}

    def pause(i: int, done: int) -> None:
        for k, cut, pieces in waiting.get(i, ()):
            twin = copy.deepcopy(ekf)
            if done < len(pieces.u):
                pieces.predict(twin, done, len(pieces.u))
            found[k] = _result(cut, twin, time.perf_counter() - started, noise, config)

    with np.errstate(all="ignore"):
        _feed(ekf, steps, pause=pause)
    full = _result(run, ekf, time.perf_counter() - started, noise, config)
    return full, tuple(found[k] for k in range(len(times)))


def prior_before(
    run: RunLog, k: int, noise: NoiseConfig | None = None, config: FilterConfig | None = None
) -> ReplayResult:
    """The state just before detection k is used: predicted to its time, detections 0..k-1 applied.

    Feeding detection k to `ekfslam.core.steps.update_steps` with this state is the step the full
    replay takes.
    """
    return replay(truncate(run, float(run.detections.t[k]), max_detections=k), noise, config)


def landmark_slots(result: ReplayResult) -> list[int]:
    """Landmark ids in the order of their slots in `result.mu` (slot j at indices 3+2j, 4+2j)."""
    ids = list(result.landmarks)
    for j, i in enumerate(ids):
        if not np.array_equal(result.mu[3 + 2 * j : 5 + 2 * j], result.landmarks[i]):
            raise EkfSlamError(f"landmark {i} is not in slot {j} of the state")
    return ids


def _feed(ekf: EKFSLAM | Recovery, steps: Schedule, *, check: bool = False, pause=None) -> None:
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
                _check_finite(ekf, f"t = {steps.t[p - 1]:.3f} s (prediction)")
        ekf.update(steps.ids[i], steps.z[i], steps.noise_of(i), steps.times[i], validate=False)
        if check:
            where = f"update of landmark {steps.ids[i]}, detection {i + 1}"
            _check_finite(ekf, f"t = {steps.times[i]:.3f} s ({where})")
    if pause is not None:
        pause(len(steps.upto), done)
    if done < len(steps.u):
        steps.predict(ekf, done, len(steps.u), validate=False)
        if check:
            _check_finite(ekf, f"t = {steps.t[-1]:.3f} s (prediction to the end)")


def _feed_hidden(
    associating: AssociatingFilter | HypothesisBank | MappingFilter,  # (DecisionReplay is one)
    steps: Schedule,
    *,
    pause=None,
) -> None:
    """`_feed` without the ids: the detections of one time are associated together.

    The ids are not looked at (the filter must not know them); the replay's pieces are the same.
    associating: an `AssociatingFilter`; a `HypothesisBank` (``mht``), which keeps no history;
    or what replays decisions already made (`DecisionReplay`, `MappingFilter`).
    pause: as `_feed`'s, called only between one time's sightings and the next.
    """
    done = 0
    for i, k in _one_time_groups(steps.times):
        if pause is not None:
            pause(i, done)
        p = steps.upto[i]
        if p > done:
            steps.predict(associating, done, p, validate=False)  # the run was checked once
            done = p
        associating.observe(steps.z[i:k], steps.Q, steps.times[i], *_body_rate(steps, p))
    if pause is not None:
        pause(len(steps.upto), done)
    if done < len(steps.u):
        steps.predict(associating, done, len(steps.u), validate=False)


def decisions_from_known_state(
    run: RunLog,
    noise: NoiseConfig | None = None,
    config: FilterConfig | None = None,
    *,
    association: AssociationConfig,
) -> NDArray[np.int64]:
    """What `association` would decide for each detection from the state the ids give.

    The run is replayed with its ids (as `replay`), and before the updates of each time the
    sightings of that time are also associated (`AssociatingFilter.decide`), which changes
    nothing. Returns (N,) the landmark id chosen for each detection, -1 for none: against the
    detections' ids, how often the method errs when its map and pose are as good as the ids
    make them, its wrong decisions not fed back.
    """
    noise = noise or default_noise(run)
    steps = schedule(run, noise)
    config = backend_for(config or default_config(run), steps.events)
    ekf = EKFSLAM(run.meta.nominal_start, None, config)
    judge = AssociatingFilter(ekf, association)
    chosen: list[int] = []
    done = 0
    with np.errstate(all="ignore"):
        for i, k in _one_time_groups(steps.times):
            p = steps.upto[i]
            if p > done:
                steps.predict(ekf, done, p)
                done = p
            chosen += judge.decide(steps.z[i:k], steps.Q, *_body_rate(steps, p))
            for a in range(i, k):
                ekf.update(steps.ids[a], steps.z[a], steps.Q, steps.times[a])
    return np.array(chosen, dtype=np.int64)


def _one_time_groups(det_time) -> Iterator[tuple[int, int]]:
    """(i, k) for each run of detections i..k-1 taken at one time (one image's sightings)."""
    i, n = 0, len(det_time)
    while i < n:
        k = i + 1
        while k < n and det_time[k] == det_time[i]:
            k += 1
        yield i, k
        i = k


def _body_rate(steps: Schedule, p: int) -> tuple[float, tuple[float, float]]:
    """rad/s and the body velocity (m/s) of the piece that ends at the sightings (a time-stamp
    error moves the pose they were taken from)."""
    if p > 0 and steps.dt[p - 1] > 0:
        vx, vy, w = (steps.u[p - 1] / steps.dt[p - 1]).tolist()
        return w, (vx, vy)
    return 0.0, (0.0, 0.0)


def _check_finite(ekf: EKFSLAM, where: str) -> None:
    if not (np.isfinite(ekf.mu).all() and np.isfinite(ekf.Sigma).all()):
        raise NonFiniteStateError(
            f"the filter state became non-finite at {where}: check the noise settings and the "
            "log's values near that time"
        )
