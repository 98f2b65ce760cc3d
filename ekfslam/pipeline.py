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
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam import checks
from ekfslam.core.association import AssociationConfig
from ekfslam.core.diagnosis import Diagnosis, diagnose
from ekfslam.core.filter.associating import AssociatingFilter, AssociationLog
from ekfslam.core.filter.backend import for_replay
from ekfslam.core.filter.config import FilterConfig, FilterCounts
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter.history import History, Keyframes
from ekfslam.core.filter.prior import PassRecord
from ekfslam.core.noise import NoiseConfig, default_config, default_noise, sighting_noise
from ekfslam.errors import ConfigError, EkfSlamError
from ekfslam.logs.edit import truncate
from ekfslam.logs.runlog import RunLog, check_replayable
from ekfslam.plausibility import MAX_HEADING, MAX_POSITION
from ekfslam.schedule import (
    NonFiniteStateError,
    Schedule,
    body_rate,
    feed,
    one_time_groups,
    schedule,
)
from ekfslam.strategies import HiddenIds, KnownIds, Start, strategy_of

Array = NDArray[np.float64]

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
    start: Start | ArrayLike | None = None,
    association: KnownIds | HiddenIds | AssociationConfig | None = None,
    keyframes: int | None = None,
) -> ReplayResult:
    """Run the EKF over a log and return the estimate with its full history.

    Parameters
    ----------
    run : RunLog
    noise : NoiseConfig, the R and Q to use (default: `default_noise(run)`). With the ids known,
        each sighting gets its own Q when the run's detections carry their σ or the noise's σ_r
        grows with the range (`ekfslam.core.noise.sighting_noise`).
    config : FilterConfig, landmark initialisation, gate (default: `default_config(run)`). With
        backend "auto", a replay whose work (`ekfslam.strategies.Strategy.work`: events, weighed
        by the association's cost) is long runs compiled, a short one as Python; for many short
        replays (a Monte Carlo, a noise fit), `batch_config` chooses for the batch.
    start : where the filter starts: a pose (3,), or a `ekfslam.strategies.Start` (the pose and
        Σ0 of eq. 2). By default the run's nominal start with Σ0 = 0 (the seed starts from its
        nominal pose and recovers the placement error afterwards, eq. 17).
    association : how sightings are matched to landmarks (`ekfslam.strategies`): `KnownIds()`
        (the default: the detections' ids; with ``recovery``, the pose covariance widened after
        a run of rejections) or `HiddenIds(AssociationConfig(...), passes, map_noise)` (the ids
        hidden from the filter, the sightings of each time associated); an `AssociationConfig`
        alone is the one its method names.
    keyframes : how many copies of the full state (μ, Σ) to keep (`History` keeps only the pose
        block), at least 2: the start, the state after evenly spread numbers of detections, and
        the end; fewer when the run has fewer detections. None (the default) keeps none and
        costs nothing. An animation's frames (`ekfslam.viz.animation`).
    """
    check_replayable(run, "replay: run")
    strategy = strategy_of(association)
    for name, value, kind, hint in (
        ("noise", noise, NoiseConfig, "e.g. NoiseConfig(sigma_range=0.05)"),
        ("config", config, FilterConfig, "e.g. FilterConfig(gate=None)"),
    ):
        if value is not None:
            checks.instance(value, kind, f"replay: {name}", hint)
    begin = _start(run, start)
    whole = isinstance(keyframes, int | np.integer) and not isinstance(keyframes, bool)
    if keyframes is not None and not (whole and 2 <= keyframes <= MAX_KEYFRAMES):
        raise ConfigError(
            f"keyframes must be a whole number from 2 to {MAX_KEYFRAMES} (each is a copy of the "
            f"whole state), got {checks.shown(keyframes)}"
        )
    noise = noise or default_noise(run)
    asked = config or default_config(run)
    strategy.check(asked)
    started = time.perf_counter()  # the schedule counts: it is part of the replay's work
    steps = schedule(run, noise)
    config = for_replay(asked, strategy.work(steps))  # "auto": compiled for a long replay
    each = sighting_noise(noise, run.detections)
    if np.ndim(each) == 3 and not strategy.hidden:  # each sighting its own Q (by range, ...)
        steps = dataclasses.replace(steps, Q=each)
    elif np.ndim(each) == 3:
        warnings.warn(
            f"run {run.meta.name!r}: with hidden ids every sighting has sigma_range and "
            "sigma_bearing; its own noise (detections.csv's sigma columns, sigma_range_per_m) "
            "is used with the ids known only",
            RuntimeWarning,
            stacklevel=2,
        )
    with np.errstate(all="ignore"):  # an overflow is caught below, once, and said where
        decided = strategy.decide(begin, config, steps, keyframes)
    seconds = time.perf_counter() - started
    ekf = decided.ekf
    frames = None if decided.taker is None else decided.taker.finish()
    if not (np.isfinite(ekf.mu).all() and np.isfinite(ekf.Sigma).all()):
        if not strategy.hidden:  # once per replay, O(n²); only on failure is the run fed
            with np.errstate(all="ignore"):  # again, checking every step, to say where
                again = EKFSLAM(begin.pose, begin.covariance, config, record=False)
                feed(again, steps, check=True)
        raise NonFiniteStateError(f"run {run.meta.name!r}: the filter state became non-finite")
    if ekf.counts.singular:
        warnings.warn(
            f"run {run.meta.name!r}: {ekf.counts.singular} updates skipped because the "
            "innovation covariance S was singular or not finite (is the noise too small or "
            "too large?)",
            RuntimeWarning,
            stacklevel=2,
        )
    map_noise = getattr(strategy, "map_noise", None)
    result = _result(
        run, ekf, seconds, noise, asked, decided.log, frames, map_noise, decided.recoveries
    )
    if not decided.passes:
        return result
    return dataclasses.replace(result, passes=decided.passes, chosen_pass=decided.chosen + 1)


def batch_config(
    run: RunLog,
    count: int,
    config: FilterConfig | None = None,
    association: KnownIds | HiddenIds | AssociationConfig | None = None,
) -> FilterConfig:
    """The config `count` replays like ``replay(run, config=config, association=association)``
    should run with in one process (a Monte Carlo, a noise fit, a sweep): with backend "auto",
    their work together decides whether the compiled steps pay for their loading
    (`ekfslam.core.filter.backend.for_replay`): twenty replays of a short run are a long one.
    Another backend is kept."""
    if not checks.is_whole(count) or int(count) < 1:
        raise ConfigError(
            f"batch_config: count must be a whole number >= 1, got {checks.shown(count)}"
        )
    config = config or default_config(run)
    if config.backend != "auto":
        return config
    work = strategy_of(association).work(schedule(run, default_noise(run)))
    return for_replay(config, work * int(count))


def _start(run: RunLog, start: Start | ArrayLike | None) -> Start:
    """`replay`'s ``start`` as a `Start` with its pose: checked, and plausible."""
    if not isinstance(start, Start):
        start = Start(pose=None if start is None else start)
    if start.pose is not None:  # its plausibility below, with the run's nominal start's
        checks.array(start.pose, "replay: start.pose", (3,), "a pose (x, y, theta)", finite=False)
    if start.covariance is not None:
        checks.covariance(start.covariance, "replay: start.covariance", 3)
    pose0 = run.meta.nominal_start if start.pose is None else start.pose
    p = np.asarray(pose0, dtype=float)
    if p.shape != (3,) or not (np.all(np.abs(p[:2]) <= MAX_POSITION) and abs(p[2]) <= MAX_HEADING):
        # a finite 1e308 start overflows in the alignment: a table of NaN, not an error
        whose = "replay: start.pose" if start.pose is not None else "the run's nominal_start"
        raise ConfigError(
            f"{whose} {p.tolist()} is not a plausible (x, y, theta): |x|, |y| <= "
            f"{MAX_POSITION:g} m, |theta| <= 2 pi rad"
        )
    return Start(pose=p, covariance=start.covariance)


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
    config = for_replay(config, steps.events)
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
        feed(ekf, steps, pause=pause)
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
    config = for_replay(config or default_config(run), steps.events)
    ekf = EKFSLAM(run.meta.nominal_start, None, config)
    judge = AssociatingFilter(ekf, association)
    chosen: list[int] = []
    done = 0
    with np.errstate(all="ignore"):
        for i, k in one_time_groups(steps.times):
            p = steps.upto[i]
            if p > done:
                steps.predict(ekf, done, p)
                done = p
            chosen += judge.decide(steps.z[i:k], steps.Q, *body_rate(steps, p))
            for a in range(i, k):
                ekf.update(steps.ids[a], steps.z[a], steps.Q, steps.times[a])
    return np.array(chosen, dtype=np.int64)
