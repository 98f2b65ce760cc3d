"""A team's logs joined to one filter: `replay_team`, cooperative EKF SLAM.

Every robot's odometry, every sighting of a landmark and every sighting of one robot by another
go through one `ekfslam.core.filter.team.TeamEKF`, in time order (the team's logs share one
clock): before an event, each robot it involves is predicted to the event's time through its
own controls, each held until its next row (eqs. 4-9); the sighting then corrects (eqs. 13-16).

Where the robots start: with every robot's ground truth (MRCLAM Datasets 6 and 7, a simulated
team), each starts at its run's nominal start (the truth at its first control), all in one
frame. Without it (Datasets 1-4), the first robot of the team (`anchor`) defines the frame at its
nominal start, and each other robot runs alone, in a filter of its own, from its own nominal
start, until its own map shares `ENTRY_LANDMARKS` landmarks with the joint map: then its map is
aligned onto the joint map (least squares), and it enters the joint state at its aligned pose,
with its own pose covariance turned into the joint frame plus the alignment's residual spread
(`Entry` records when, how and from which landmarks). Its sightings before entry built its own
map only, and are counted as such.

Or it enters from robots already placed, whichever comes first: each sighting between it and a
placed robot (it sees the placed robot's barcode, or the placed robot sees its own) gives one
point in two frames: in the joint frame (the placed robot's centre, or the placed robot's pose
and the sighting, eq. 12's g) and in a local frame the unplaced robot dead-reckons from its own
odometry since its first such sighting (its own centre, or g of its local pose and the
sighting). The rigid transform between the frames is fitted to the points by weighted least
squares (Gauss-Newton from `weighted_kabsch`, each point weighted by the inverse covariance of
its sighting noise and of the local pose), and the robot enters at that transform of its local
pose once `ENTRY_ROBOT_SIGHTINGS` sightings within `ENTRY_WINDOW` s fit (χ² 99%) and fix its
pose to `ENTRY_POSITION_SIGMA` and `ENTRY_HEADING_SIGMA`. Its covariance is the fit's, to first
order: the sightings' and the dead reckoning's noise, and, through eq. 12's form, the placed
robots' pose errors, so it enters correlated with them and, through them, with the map
(`ekfslam.core.filter.team.TeamEKF.add_robot`'s ``depends``).
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import math
import time
from collections import Counter
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ekfslam import checks
from ekfslam.core.association import UNPAIRED, AssociationConfig
from ekfslam.core.diagnosis import Diagnosis, diagnose_sightings
from ekfslam.core.filter.associating import AssociatingFilter
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.history import Outcome
from ekfslam.core.filter.team import RobotView, TeamEKF
from ekfslam.core.noise import NoiseConfig, default_config, default_noise
from ekfslam.core.recovery import Recovery, RecoveryConfig
from ekfslam.errors import AlignmentError, ConfigError
from ekfslam.geometry import compose, rotation, weighted_kabsch, wrap_angle
from ekfslam.logs.mrclam import defaults as mrclam_defaults
from ekfslam.logs.team import TeamLog, check_team

Array = NDArray[np.float64]

#: A team's recovery by default: the single replay's rule (`RecoveryConfig()`). On MRCLAM
#: Dataset 7 robot 3 runs 23 s without a sighting at 330 s and drifts 0.8 m; without recovery
#: every later sighting fails the gate and it ends 1.8 m off (ATE), with it 0.20 m.
DEFAULT_RECOVERY = RecoveryConfig()
#: Landmarks a robot's own map must share with the joint map before the robot enters it.
ENTRY_LANDMARKS = 3
#: m: how far apart the shared landmarks must be (the largest distance between two), so the
#: alignment's rotation is determined.
ENTRY_SPREAD = 1.0
#: m: the largest rms distance of the shared landmarks after the alignment for the robot to
#: enter; a worse fit waits for more landmarks (its own map is still settling).
ENTRY_RESIDUAL = 0.15
#: Sightings between an unplaced robot and placed ones before it may enter from them (3: the
#: fit of a 3-parameter pose to 2 numbers each has 3 degrees of freedom left to test it with).
ENTRY_ROBOT_SIGHTINGS = 3
#: s: the sightings an entry from robots uses are the last ones within this time (the placed
#: robots' errors are taken as one error each over it; the dead reckoning drifts beyond it).
ENTRY_WINDOW = 20.0
#: m and rad: how well the sightings must fix the entering pose (its σ: the largest of the
#: position's axes, and the heading's).
ENTRY_POSITION_SIGMA = 0.1
ENTRY_HEADING_SIGMA = 0.05
#: The χ² probability the entry fit's residual must pass (else the oldest sighting is dropped).
ENTRY_FIT_PROBABILITY = 0.99
#: s: with hidden ids, how often an unplaced robot's own map is matched to the joint map again
#: when it has not grown (`replay_team`'s ``match_maps``).
MATCH_EVERY = 1.0


@dataclass(frozen=True, eq=False)
class Entry:
    """How a robot entered the joint state.

    t : s on the team's clock. seconds : s after the team's first control row.
    how : "start" (its known start, with the others'), "anchor" (its nominal start defines the
        frame), "landmarks" (its own map aligned onto the joint map) or "robots" (sightings
        between it and robots already placed, module docstring).
    landmarks : the shared landmarks' ids (for "landmarks").
    residual : m, rms distance of the shared landmarks, or of the sightings' points, after the
        alignment (for "landmarks", "robots").
    robots : the placed robots whose sightings placed it (for "robots").
    sightings : how many sightings placed it (for "robots").
    pose : (3,) where it entered, in the joint frame. covariance : (3, 3) its pose covariance
        then (for "robots" with its correlation to the placed robots besides, module docstring).
    """

    t: float
    seconds: float
    how: str
    landmarks: tuple[int, ...] = ()
    residual: float = 0.0
    robots: tuple[int, ...] = ()
    sightings: int = 0
    pose: Array = field(default_factory=lambda: np.full(3, np.nan))
    covariance: Array = field(default_factory=lambda: np.full((3, 3), np.nan))

    def describe(self) -> str:
        """One phrase: when and how."""
        if self.how == "start":
            return "at its known start"
        if self.how == "anchor":
            return "at its nominal start, which defines the map's frame"
        if self.how == "robots":
            names = ", ".join(map(str, self.robots))
            return (
                f"after {self.seconds:.1f} s, placed by {self.sightings} sightings between it "
                f"and robot{'s' if len(self.robots) > 1 else ''} {names} (residual "
                f"{self.residual:.3f} m)"
            )
        ids = ", ".join(map(str, self.landmarks))
        return (
            f"after {self.seconds:.1f} s, placed by its own map's landmarks {ids} (residual "
            f"{self.residual:.3f} m)"
        )


@dataclass(frozen=True, eq=False)
class RobotTrack:
    """One robot's estimate at each of its events: t (K,) s, pose (K, 3), and its counts.

    landmarks, robots_seen : {outcome label: count} of its sightings of landmarks and of other
        robots in the joint state; seen_by : how many sightings of it others used (accepted).
    alone : landmark sightings it used in its own filter before it entered.
    skipped : robot sightings before the observer or the target entered (or before its log).
    recoveries : s on the team's clock, when recovery widened its pose covariance.
    lost_at_end : its last `RecoveryConfig.after` (20) landmark sightings were all rejected: its
        pose at the end cannot be trusted.
    diagnosis : does its replay agree with its data (`ekfslam.core.diagnosis.diagnose_sightings`:
        a single replay's diagnosis, over its landmark sightings, alone before it entered and in
        the joint filter after), its times from its first control.
    estimated : hidden ids: (M,) the joint map's landmark id each of its M detections was used
        for (`ekfslam.core.association.UNPAIRED`: none, or it had not entered), for scoring
        (`ekfslam.analysis.association.score_team`); None with the ids known.
    association : hidden ids: its `AssociationCounts` (alone and in the joint map), else None.
    """

    t: Array
    pose: Array
    landmarks: dict[str, int]
    robots_seen: dict[str, int]
    seen_by: int
    alone: int
    skipped: int
    recoveries: tuple[float, ...] = ()
    lost_at_end: bool = False
    diagnosis: Diagnosis | None = None
    estimated: Array | None = None
    association: dict[str, int] | None = None


@dataclass(frozen=True, eq=False)
class TeamResult:
    """What `replay_team` gives back.

    name : the team's. robots : their numbers. landmarks : {id: (x, y)} the joint map, and its
    covariances. mu, Sigma : the final joint state (robots in `rows` order, then landmarks).
    tracks : {robot: `RobotTrack`}. entries : {robot: `Entry`}. seconds : wall time of the loop.
    decided : with hidden ids and a ``map_noise``, the deciding pass's result (this one is the
        mapping pass's, its tracks carrying the deciding pass's decisions); else None.
    """

    name: str
    robots: tuple[int, ...]
    landmarks: dict[int, Array]
    landmark_covariances: dict[int, Array]
    mu: Array
    Sigma: Array
    rows: dict[int, int]
    tracks: dict[int, RobotTrack]
    entries: dict[int, Entry]
    seconds: float
    decided: TeamResult | None = None


class _OneRobot:
    """One robot's view of the joint filter, with the single filter's step names, so that
    `ekfslam.core.recovery.Recovery` watches it as it watches a single replay."""

    def __init__(self, joint: TeamEKF, robot: int) -> None:
        self.joint, self.robot = joint, robot

    @property
    def pose(self) -> Array:
        return self.joint.pose(self.robot)

    def landmark(self, landmark_id: int) -> tuple[Array, Array]:
        return self.joint.landmark(landmark_id)

    def predict(self, u: Array, R: Array, t: float | None = None) -> None:
        if np.any(u):
            raise ValueError("a team robot's widening is a prediction with no motion")
        self.joint.widen(self.robot, R)

    def update(self, landmark_id: int, z, Q, t: float | None = None) -> Outcome:
        return self.joint.update(self.robot, z, landmark_id, Q)


@dataclass
class _Robot:
    """A robot's prediction pieces and where the replay is in them."""

    breaks: Array  # (P + 1,) s: its control times and its events' times
    u: Array  # (P, 3) the increments between breaks
    dt: Array  # (P,) s, their durations
    N: Array  # (3, 3) the control noise per second of driving
    done: int = 0  # pieces predicted
    times: list = field(default_factory=list)
    poses: list = field(default_factory=list)
    landmarks: Counter = field(default_factory=Counter)
    robots_seen: Counter = field(default_factory=Counter)
    seen_by: int = 0
    alone: int = 0
    skipped: int = 0
    recovery: Recovery | None = None
    rejected_in_a_row: int = 0
    sighted: list = field(default_factory=list)  # (t, landmark, NIS, Outcome) for the diagnosis
    chooser: AssociatingFilter | None = None  # hidden ids: decides its sightings (`RobotView`)
    estimated: Array | None = None  # hidden ids: the joint map's id each detection was used for
    association: Counter = field(default_factory=Counter)  # hidden ids: the choosers' counts
    tried: tuple = (-1, -math.inf)  # hidden ids: own map's size and the time of the last match
    local: TeamEKF | None = None  # unplaced: dead reckoning since its first sighting of a placed
    ties: list = field(default_factory=list)  # ... robot, and those sightings' points (`_Tie`)


#: A source's `replay_team` ``robot_noise_scale`` by `RunMeta.defaults` name (else 1).
ROBOT_NOISE_SCALES = {mrclam_defaults.NAME: mrclam_defaults.MRCLAM_ROBOT_NOISE_SCALE}

#: Rejected sightings in a row at the end of a run that mark a robot as lost (`RobotTrack`).
LOST_AFTER = RecoveryConfig().after


def replay_team(
    team: TeamLog,
    noise: NoiseConfig | Mapping[int, NoiseConfig] | None = None,
    config: FilterConfig | None = None,
    *,
    robot_sightings: bool = True,
    anchor: int | None = None,
    recovery: RecoveryConfig | None = DEFAULT_RECOVERY,
    known_starts: bool | None = None,
    robot_entry: bool = True,
    association: AssociationConfig | None = None,
    match_maps: Callable | None = None,
    map_noise: NoiseConfig | Mapping[int, NoiseConfig] | None = None,
    backend: str = "numba",
    robot_noise_scale: float | None = None,
) -> TeamResult:
    """Replay a team through one joint filter (module docstring).

    Parameters
    ----------
    team : `ekfslam.logs.team.TeamLog` (`ekfslam.logs.mrclam.team.load_mrclam_team`,
        `ekfslam.sim.team.simulate_team`).
    noise : one `NoiseConfig` for every robot, or {robot: NoiseConfig}; by default each run's
        own (`default_noise`). A robot's sightings of another use the observer's σ_r and σ_φ.
    config : the gate (`FilterConfig.gate`); by default the first run's (`default_config`).
    robot_sightings : False ignores the robots' sightings of one another (the team then maps
        together only through the shared landmarks: the baseline a study compares with).
    anchor : without every robot's ground truth, the robot whose nominal start defines the
        frame (default: the team's first).
    known_starts : whether every robot starts at its run's nominal start, in one frame; None
        (the default): when every run has its ground truth. False places them as the module
        says, even with ground truth (a study of the placement on Dataset 7).
    recovery : each robot's pose covariance widened after a run of its landmark sightings are
        rejected (`ekfslam.core.recovery`, as a single replay's ``recovery``); None: never.
    robot_entry : a robot whose start is unknown may enter from its sightings with robots
        already placed (module docstring); False: from its own map's landmarks only.
    association : None (or method "known"): the sightings' landmark ids. "nn" or "jcbb"
        (`ekfslam.core.association.AssociationConfig`): the landmark ids hidden, each robot's
        sightings of one time associated against the joint map (before it entered, against its
        own) by `ekfslam.core.filter.associating.AssociatingFilter`, as a single replay's are;
        the robots' barcodes stay known (they name robots, not landmarks). One filter decides
        and maps (no second mapping filter, as a single MRCLAM replay has).
    match_maps : with hidden ids, how a robot's own map is matched to the joint map for its
        entry from landmarks: (own {id: (x, y)}, joint {id: (x, y)}) -> an object whose
        ``mapping`` is {own id: joint id} (`ekfslam.analysis.alignment_unlabelled.
        match_by_position`); None: a robot whose start is unknown enters from robots only.
    map_noise : with hidden ids, the noise of a second, mapping pass that replays the
        decisions (each sighting named by the joint map's id it was used for), as a single
        hidden-id replay's mapping filter does (`ekfslam.pipeline.replay`'s ``map_noise``;
        MRCLAM's: `ekfslam.logs.hidden_ids.HiddenIdDefaults.map_noise`); None: the deciding
        filter maps.
    robot_noise_scale : the σ_r and σ_φ of a sighting of a robot, as a multiple of the
        observer's landmark sightings'; None (the default): the source's (MRCLAM's
        `ekfslam.logs.mrclam.defaults.MRCLAM_ROBOT_NOISE_SCALE`, 0.5), else 1 (the same camera,
        the same noise: a simulated team's).
    backend : the association's step functions ("numba", compiled, the default: JCBB's
        predictions interpreted cost 20x; or "python").

    Raises
    ------
    ValueError
        A team `check_team` refuses.
    ConfigError
        Noise with a fixed per-step R (`NoiseConfig.R_per_step`: the team predicts per second
        of driving), or an anchor not in the team.
    """
    check_team(team)
    name = "replay_team"
    robot_sightings = checks.flag(robot_sightings, f"{name}: robot_sightings")
    robot_entry = checks.flag(robot_entry, f"{name}: robot_entry")
    if known_starts is not None:
        known_starts = checks.flag(known_starts, f"{name}: known_starts")
    if anchor is not None:
        anchor = checks.whole(anchor, f"{name}: anchor")
    backend = checks.choice(backend, f"{name}: backend", ("numba", "python"))
    for what, value, kind in (
        ("config", config, FilterConfig),
        ("recovery", recovery, RecoveryConfig),
        ("association", association, AssociationConfig),
    ):
        if value is not None:
            checks.instance(value, kind, f"{name}: {what}")
    if robot_noise_scale is None:
        robot_noise_scale = ROBOT_NOISE_SCALES.get(team.runs[team.robots[0]].meta.defaults, 1.0)
    robot_noise_scale = checks.real(
        robot_noise_scale, f"{name}: robot_noise_scale", lo=0.0, lo_open=True, hi=1e6
    )
    hidden = association is not None and association.method != "known"
    if hidden and association.method not in ("nn", "jcbb"):
        raise ConfigError(
            f"replay_team: association {association.method!r} is not available for a team "
            "(nn or jcbb)"
        )
    robots = team.robots
    noises = _noises(team, noise)
    config = config or default_config(team.runs[robots[0]])
    known_starts = team.has_starts if known_starts is None else bool(known_starts)
    anchor = robots[0] if anchor is None else anchor
    if anchor not in team.runs:
        raise ConfigError(f"replay_team: anchor robot {anchor} is not in the team {robots}")
    started = time.perf_counter()

    joint = TeamEKF(gate=config.gate, capacity=3 * len(robots) + 64)
    alone: dict[int, TeamEKF] = {}
    entries: dict[int, Entry] = {}
    t0 = team.span()[0]
    for robot in robots:
        run = team.runs[robot]
        if known_starts or robot == anchor:
            joint.add_robot(robot, run.meta.nominal_start)
            how = "start" if known_starts else "anchor"
            entries[robot] = Entry(
                t=float(run.controls.t[0]),
                seconds=0.0,
                how=how,
                pose=joint.pose(robot),
                covariance=joint.pose_covariance(robot),
            )
        else:
            alone[robot] = TeamEKF(gate=config.gate)
            alone[robot].add_robot(robot, run.meta.nominal_start)

    times, kinds, who, index = _events(team, robot_sightings)
    state = {
        r: _pieces(team.runs[r], times[(who[:, 0] == r) | (who[:, 1] == r)], noises[r])
        for r in robots
    }
    Q_of = {r: noises[r].Q for r in robots}
    Q_robot = {r: Q * robot_noise_scale**2 for r, Q in Q_of.items()}
    for r in robots:
        if hidden:
            state[r].estimated = np.full(len(team.runs[r].detections.t), UNPAIRED, np.int64)
    sightings = team.sightings

    def use(robot: int, landmark_id: int, z, Q: Array, t: float) -> Outcome:
        """Correct with one landmark sighting of `robot`: the joint filter's (with recovery),
        or, before it entered, its own filter's; counted for its diagnosis."""
        s = state[robot]
        if robot in joint.rows:
            if s.recovery is None and recovery is not None:
                s.recovery = Recovery(_OneRobot(joint, robot), recovery)
            outcome = (s.recovery or _OneRobot(joint, robot)).update(landmark_id, z, Q, t)
            s.sighted.append((t, landmark_id, joint.last_nis, int(outcome)))
            s.landmarks[outcome.label] += 1
            if outcome == Outcome.REJECTED:
                s.rejected_in_a_row += 1
            elif outcome == Outcome.ACCEPTED:
                s.rejected_in_a_row = 0
        else:
            outcome = alone[robot].update(robot, z, landmark_id, Q)
            s.sighted.append((t, landmark_id, alone[robot].last_nis, int(outcome)))
            s.alone += 1
        return outcome

    n_events, i = len(times), 0
    while i < n_events:
        t, kind, (a, b), k = times[i], kinds[i], who[i], index[i]
        if kind == 0:  # robot a sees landmark k of its run (hidden ids: all it saw at t)
            j = i + 1
            while hidden and j < n_events and kinds[j] == 0 and times[j] == t and who[j, 0] == a:
                j += 1
            ks, i, a = index[i:j], j, int(a)
            s = state[a]
            if not _predict_to(s, t, joint if a in joint.rows else alone.get(a), a):
                s.skipped += len(ks)
                continue
            det = team.runs[a].detections
            if hidden:  # associated against the map as a single replay's are
                if s.chooser is None:
                    view = RobotView(
                        joint if a in joint.rows else alone[a],
                        a,
                        functools.partial(_use_as_view, use, a),
                        backend,
                    )
                    s.chooser = AssociatingFilter(view, association)
                zs = np.column_stack([det.range[ks], det.bearing[ks]])
                used = s.chooser.observe(zs, Q_of[a], t, *_body_rate(s, t))
                if a in joint.rows:
                    s.estimated[ks] = used
            else:
                use(a, int(det.tag_id[k]), (det.range[k], det.bearing[k]), Q_of[a], t)
            if a in joint.rows:
                _record(s, t, joint.pose(a))
                continue
            entry = _try_entry(alone[a], joint, a, t, t0, s, match_maps if hidden else None)
            if entry is not None:
                entries[a] = entry
                del alone[a]
                s.local, s.ties = None, []
                _finish_chooser(s)
                _record(s, t, joint.pose(a))
            continue
        i += 1
        if kind == 1:  # robot a sees robot b: sighting k of the team's
            if a not in joint.rows or b not in joint.rows:
                placed_a, placed_b = a in joint.rows, b in joint.rows
                ok_a = _predict_to(state[a], t, joint if placed_a else alone.get(a), a)
                ok_b = _predict_to(state[b], t, joint if placed_b else alone.get(b), b)
                state[a].skipped += 1
                if robot_entry and ok_a and ok_b and placed_a != placed_b:
                    u, p = (int(b), int(a)) if placed_a else (int(a), int(b))
                    z = (sightings.range[k], sightings.bearing[k])
                    _tie(state[u], joint, _Tie(t, u, p, observer=a, z=z, Q=Q_robot[a]))
                    entry = _try_robot_entry(state[u], joint, u, t, t0)
                    if entry is not None:
                        entries[u] = entry
                        del alone[u]
                        state[u].local, state[u].ties = None, []
                        _finish_chooser(state[u])
                        _record(state[u], t, joint.pose(u))
                continue
            ok_a = _predict_to(state[a], t, joint, a)
            ok_b = _predict_to(state[b], t, joint, b)
            if not (ok_a and ok_b):
                state[a].skipped += 1
                continue
            z = (sightings.range[k], sightings.bearing[k])
            outcome = joint.update_robot(a, b, z, Q_robot[a])
            state[a].robots_seen[outcome.label] += 1
            state[b].seen_by += outcome == Outcome.ACCEPTED
            _record(state[a], t, joint.pose(a))
            _record(state[b], t, joint.pose(b))
    for robot in robots:
        _finish_chooser(state[robot])
    for robot in robots:  # the rest of each robot's controls
        filt = joint if robot in joint.rows else alone[robot]
        _predict_to(state[robot], state[robot].breaks[-1], filt, robot)
        _record(state[robot], state[robot].breaks[-1], filt.pose(robot))
    seconds = time.perf_counter() - started

    tracks = {r: _track(state[r]) for r in robots}
    decided = TeamResult(
        name=team.name,
        robots=robots,
        landmarks=joint.landmark_map(),
        landmark_covariances=joint.landmark_covariances(),
        mu=joint.mu,
        Sigma=joint.Sigma,
        rows=dict(joint.rows),
        tracks=tracks,
        entries=entries,
        seconds=seconds,
    )
    if not hidden or map_noise is None:
        return decided
    # the decisions replayed with the ids they gave, by a filter with the mapping noise
    mapped = replay_team(
        _as_decided(team, decided),
        map_noise,
        config,
        robot_sightings=robot_sightings,
        anchor=anchor,
        recovery=recovery,
        known_starts=known_starts,
        robot_entry=robot_entry,
        robot_noise_scale=robot_noise_scale,
    )
    kept = {
        r: dataclasses.replace(
            mapped.tracks[r], estimated=tracks[r].estimated, association=tracks[r].association
        )
        for r in robots
    }
    return dataclasses.replace(
        mapped, tracks=kept, seconds=time.perf_counter() - started, decided=decided
    )


def _as_decided(team: TeamLog, decided: TeamResult) -> TeamLog:
    """The team with each robot's detections named by the joint map's ids its decisions gave
    them, those used for none left out: the mapping pass of a hidden-id replay."""
    runs = {}
    for robot, run in team.runs.items():
        d, used = run.detections, decided.tracks[robot].estimated
        keep = used != UNPAIRED
        sigmas = {}
        if d.has_sigmas:
            sigmas = {"sigma_range": d.sigma_range[keep], "sigma_bearing": d.sigma_bearing[keep]}
        detections = dataclasses.replace(
            d,
            t=d.t[keep],
            tag_id=used[keep],
            range=d.range[keep],
            bearing=d.bearing[keep],
            **sigmas,
        )
        runs[robot] = dataclasses.replace(run, detections=detections)
    return TeamLog(team.name, runs, team.sightings)


# ------------------------------------------------------------------------------- plumbing
def _noises(team: TeamLog, noise) -> dict[int, NoiseConfig]:
    if noise is None:
        chosen = {r: default_noise(run) for r, run in team.runs.items()}
    elif isinstance(noise, NoiseConfig):
        chosen = dict.fromkeys(team.runs, noise)
    elif isinstance(noise, Mapping):
        chosen = {r: noise.get(r) or default_noise(team.runs[r]) for r in team.runs}
    else:
        checks.instance(noise, (NoiseConfig, Mapping), "replay_team: noise")
    for robot, n in chosen.items():
        if not isinstance(n, NoiseConfig):
            raise ConfigError(f"replay_team: robot {robot}'s noise is not a NoiseConfig: {n!r}")
        if n.R_per_step is not None:
            raise ConfigError(
                f"replay_team: robot {robot}'s noise has a fixed R_per_step; the team predicts "
                "with the noise per second of driving (sigma_x, sigma_y, sigma_theta)"
            )
    return chosen


def _events(team: TeamLog, robot_sightings: bool):
    """Every sighting in time order: times (E,), kinds (0 landmark, 1 robot), who (E, 2)
    (observer, target or -1) and the row in its table. Ties: landmarks first, in robot order."""
    parts_t, parts_kind, parts_who, parts_k = [], [], [], []
    for robot in team.robots:
        det = team.runs[robot].detections
        n = len(det.t)
        parts_t.append(det.t)
        parts_kind.append(np.zeros(n, np.int64))
        parts_who.append(np.column_stack([np.full(n, robot), np.full(n, -1)]))
        parts_k.append(np.arange(n))
    s = team.sightings
    if robot_sightings and len(s):
        parts_t.append(s.t)
        parts_kind.append(np.ones(len(s), np.int64))
        parts_who.append(np.column_stack([s.observer, s.target]))
        parts_k.append(np.arange(len(s)))
    times = np.concatenate(parts_t)
    kinds = np.concatenate(parts_kind)
    order = np.lexsort((kinds, times))  # stable within equal keys: robot order, file order
    who = np.concatenate(parts_who).astype(np.int64)
    return times[order], kinds[order], who[order], np.concatenate(parts_k)[order]


def _pieces(run, event_times: Array, noise: NoiseConfig) -> _Robot:
    """A robot's prediction pieces: its control times and its events' times (inside its
    controls), each piece driven by the control row in force at its start."""
    c_t = run.controls.t
    twist = run.control_twist()
    inside = event_times[(event_times >= c_t[0]) & (event_times <= c_t[-1])]
    breaks = np.union1d(c_t, inside)
    dt = np.diff(breaks)
    row = np.searchsorted(c_t, breaks[:-1], side="right") - 1
    u = twist[row] * dt[:, None]
    return _Robot(breaks=breaks, u=u, dt=dt, N=noise.motion_density())


def _predict_to(robot: _Robot, t: float, filt: TeamEKF | None, number: int) -> bool:
    """Predict through the robot's pieces up to time t; False when t is outside its controls."""
    if filt is None or t < robot.breaks[0] or t > robot.breaks[-1]:
        return False
    k = int(np.searchsorted(robot.breaks, t, side="left"))
    if k > robot.done:
        us, dts = robot.u[robot.done : k], robot.dt[robot.done : k]
        filt.predict_many(number, us, dts, robot.N)
        if robot.local is not None:  # its dead reckoning toward an entry from robots
            robot.local.predict_many(number, us, dts, robot.N)
        robot.done = k
    return True


def _record(robot: _Robot, t: float, pose: Array) -> None:
    robot.times.append(float(t))
    robot.poses.append(pose)


def _track(robot: _Robot) -> RobotTrack:
    recoveries = tuple(robot.recovery.times) if robot.recovery is not None else ()
    sighted = np.array(robot.sighted, dtype=float).reshape(-1, 4)  # t, landmark, NIS, outcome
    ids, outcomes = sighted[:, 1].astype(np.int64), sighted[:, 3].astype(np.int8)
    span = (float(robot.breaks[0]), float(robot.breaks[-1]))
    return RobotTrack(
        t=np.array(robot.times),
        pose=np.array(robot.poses).reshape(-1, 3),
        landmarks=dict(robot.landmarks),
        robots_seen=dict(robot.robots_seen),
        seen_by=robot.seen_by,
        alone=robot.alone,
        skipped=robot.skipped,
        recoveries=recoveries,
        lost_at_end=robot.rejected_in_a_row >= LOST_AFTER,
        diagnosis=diagnose_sightings(span, sighted[:, 0], ids, sighted[:, 2], outcomes, recoveries),
        estimated=robot.estimated,
        association=dict(robot.association) if robot.estimated is not None else None,
    )


def _try_entry(
    own: TeamEKF, joint: TeamEKF, robot: int, t: float, t0: float, s: _Robot, match_maps=None
) -> Entry | None:
    """Enter `robot` into the joint state when its own map shares enough spread landmarks: by
    id, or, with hidden ids, as `match_maps` matches the maps (tried when its own map grew, or
    a second after the last try)."""
    if match_maps is None:
        pairs = [(i, i) for i in sorted(own.slot.keys() & joint.slot.keys())]
    else:
        if len(own.slot) < ENTRY_LANDMARKS or len(joint.slot) < ENTRY_LANDMARKS:
            return None
        if s.tried[0] == len(own.slot) and t - s.tried[1] < MATCH_EVERY:
            return None
        s.tried = (len(own.slot), t)
        try:
            mapping = match_maps(own.landmark_map(), joint.landmark_map()).mapping
        except AlignmentError:
            return None
        pairs = sorted(mapping.items())
    if len(pairs) < ENTRY_LANDMARKS:
        return None
    shared = [j for _, j in pairs]
    mine, theirs = own.landmark_map(), joint.landmark_map()
    X = np.array([mine[i] for i, _ in pairs])
    Y = np.array([theirs[j] for _, j in pairs])
    spread = max(float(np.hypot(*(p - q))) for p, q in _pairs(Y))
    if spread < ENTRY_SPREAD:
        return None
    T = weighted_kabsch(X, Y, np.ones(len(X)))
    residual = X @ rotation(T[2]).T + T[:2] - Y
    rms = float(np.sqrt(np.mean(np.sum(residual**2, axis=1))))
    if rms > ENTRY_RESIDUAL:
        return None
    pose = compose(T, own.pose(robot))
    J = np.eye(3)
    J[:2, :2] = rotation(T[2])
    P = J @ own.pose_covariance(robot) @ J.T
    P += np.diag([rms**2, rms**2, (rms / spread) ** 2]) * (1.0 + 1.0 / len(shared))
    joint.add_robot(robot, pose, P)
    return Entry(
        t=float(t),
        seconds=float(t - t0),
        how="landmarks",
        landmarks=tuple(shared),
        residual=rms,
        pose=joint.pose(robot),
        covariance=joint.pose_covariance(robot),
    )


@dataclass(frozen=True)
class _Tie:
    """A sighting between unplaced robot `unplaced` and placed robot `placed`, at time t."""

    t: float
    unplaced: int
    placed: int
    observer: int
    z: tuple[float, float]
    Q: Array


@dataclass(frozen=True)
class _Point:
    """One sighting's point in the two frames: X (2,) in the unplaced robot's local frame with
    covariance C_X, Y (2,) in the joint frame with covariance C_Y (its sighting noise), and B
    (2, 3) = ∂Y/∂(the placed robot's pose)."""

    t: float
    placed: int
    X: Array
    C_X: Array
    Y: Array
    C_Y: Array
    B: Array


def _tie(robot: _Robot, joint: TeamEKF, tie: _Tie) -> None:
    """Add a sighting's point (`_Point`) to the unplaced robot's list, after dropping those older
    than `ENTRY_WINDOW`; with none left, its local frame starts again at its pose now."""
    robot.ties = [p for p in robot.ties if tie.t - p.t <= ENTRY_WINDOW]
    u = tie.unplaced
    if not robot.ties or robot.local is None:
        robot.local = TeamEKF(gate=None, capacity=3)
        robot.local.add_robot(u, np.zeros(3))
    local, local_P = robot.local.pose(u), robot.local.pose_covariance(u)
    placed = joint.pose(tie.placed)
    z, Q, sensor = np.asarray(tie.z, dtype=float), tie.Q, joint.sensor
    if tie.observer == u:  # it sees the placed robot's centre: eq. (12) in its local frame
        G_r, G_z = sensor.G(local, z)
        X, C_X = sensor.g(local, z), G_r @ local_P @ G_r.T + G_z @ Q @ G_z.T
        Y, C_Y, B = placed[:2].copy(), np.zeros((2, 2)), np.eye(2, 3)
    else:  # the placed robot sees it: eq. (12) in the joint frame
        G_r, G_z = sensor.G(placed, z)
        X, C_X = local[:2].copy(), local_P[:2, :2]
        Y, C_Y, B = sensor.g(placed, z), G_z @ Q @ G_z.T, G_r
    robot.ties.append(_Point(tie.t, tie.placed, X, C_X, Y, C_Y, B))


def _try_robot_entry(robot: _Robot, joint: TeamEKF, u: int, t: float, t0: float) -> Entry | None:
    """Enter unplaced robot `u` from its sightings' points (module docstring), or None."""
    points = robot.ties
    if len(points) < ENTRY_ROBOT_SIGHTINGS:
        return None
    fit = _fit_frames(points)
    if fit is None:
        return None
    if fit.chi2 > _chi2_quantile(2 * len(points) - 3, ENTRY_FIT_PROBABILITY):
        robot.ties = points[1:]  # an outlier among them: let the oldest go
        return None
    T = fit.T
    local, local_P = robot.local.pose(u), robot.local.pose_covariance(u)
    pose = compose(T, local)
    J_T = np.eye(3)  # ∂(T ⊕ local)/∂T
    J_T[:2] = _fit_jacobian(T, local[None, :2])[0]
    J_local = np.eye(3)  # ∂(T ⊕ local)/∂local
    J_local[:2, :2] = rotation(T[2])
    cov_T = np.linalg.inv(fit.information)
    noise = J_T @ cov_T @ J_T.T + J_local @ local_P @ J_local.T
    # δT = cov_T Σ_k J_kᵀ W_k (δY_k - R δX_k), δY_k = B_k δ(its placed robot's pose) + noise
    placed = np.array([p.placed for p in points])
    B = np.array([p.B for p in points])
    JtWB = np.einsum("kji,kjl,klm->kim", fit.J, fit.W, B)
    depends = {int(q): J_T @ cov_T @ JtWB[placed == q].sum(axis=0) for q in np.unique(placed)}
    Sigma = joint.Sigma
    P = noise.copy()
    for q, A_q in depends.items():
        for w, A_w in depends.items():
            rq, rw = joint.rows[q], joint.rows[w]
            P += A_q @ Sigma[rq : rq + 3, rw : rw + 3] @ A_w.T
    position = math.sqrt(max(np.linalg.eigvalsh(P[:2, :2])))
    if position > ENTRY_POSITION_SIGMA or math.sqrt(P[2, 2]) > ENTRY_HEADING_SIGMA:
        return None
    joint.add_robot(u, pose, noise, depends=depends)
    return Entry(
        t=float(t),
        seconds=float(t - t0),
        how="robots",
        residual=fit.rms,
        robots=tuple(sorted(depends)),
        sightings=len(points),
        pose=joint.pose(u),
        covariance=joint.pose_covariance(u),
    )


def _fit_jacobian(T: Array, X: Array) -> Array:
    """∂(R(α) X_k + t)/∂(t, α) of each point X (K, 2): (K, 2, 3)."""
    c, s = math.cos(T[2]), math.sin(T[2])
    J = np.zeros((len(X), 2, 3))
    J[:, 0, 0] = J[:, 1, 1] = 1.0
    J[:, 0, 2] = -s * X[:, 0] - c * X[:, 1]
    J[:, 1, 2] = c * X[:, 0] - s * X[:, 1]
    return J


@dataclass(frozen=True)
class _Fit:
    """`_fit_frames`' answer: T (x, y, α), its information Σ Jᵀ W J (3, 3), the χ² Σ rᵀ W r,
    the rms |r| (m), and each point's J (K, 2, 3) and W (K, 2, 2) at T."""

    T: Array
    information: Array
    chi2: float
    rms: float
    J: Array
    W: Array


def _fit_frames(points: list[_Point], iterations: int = 4) -> _Fit | None:
    """The transform T (x, y, α) from the local frame to the joint frame that minimises
    Σ rᵀ W r, r = R X + t - Y, W = (R C_X Rᵀ + C_Y)⁻¹ (Gauss-Newton from `weighted_kabsch`),
    or None when the points do not fix it (the information is singular)."""
    X = np.array([p.X for p in points])
    Y = np.array([p.Y for p in points])
    C_X = np.array([p.C_X for p in points])
    C_Y = np.array([p.C_Y for p in points])
    w = 1.0 / (np.trace(C_X, axis1=1, axis2=2) + np.trace(C_Y, axis1=1, axis2=2))
    T = weighted_kabsch(X, Y, w)
    for k in range(iterations + 1):
        R = rotation(T[2])
        C = np.einsum("ij,kjl,ml->kim", R, C_X, R) + C_Y
        det = C[:, 0, 0] * C[:, 1, 1] - C[:, 0, 1] * C[:, 1, 0]
        W = np.stack([C[:, 1, 1], -C[:, 0, 1], -C[:, 1, 0], C[:, 0, 0]], axis=1)
        W = W.reshape(-1, 2, 2) / det[:, None, None]
        r = X @ R.T + T[:2] - Y
        J = _fit_jacobian(T, X)
        JtW = np.einsum("kji,kjl->kil", J, W)
        info = np.einsum("kil,klm->im", JtW, J)
        # singular: the points leave the rotation (or all of it) free
        if not np.all(det > 0.0) or np.linalg.det(info) <= 1e-12 * np.trace(info) ** 3:
            return None
        step = np.linalg.solve(info, np.einsum("kil,kl->i", JtW, r))
        if k == iterations or np.max(np.abs(step)) < 1e-10:
            break
        T = T - step
        T[2] = wrap_angle(T[2])
    chi2 = float(np.einsum("ki,kij,kj->", r, W, r))
    rms = float(np.sqrt(np.mean(np.sum(r**2, axis=1))))
    return _Fit(T=T, information=info, chi2=chi2, rms=rms, J=J, W=W)


@functools.cache
def _chi2_quantile(dof: int, p: float) -> float:
    """χ² quantile at probability p (scipy's incomplete gamma; scipy.special is loaded when a
    robot first tries to enter from robots, not with this module)."""
    special = importlib.import_module("scipy.special")
    return float(2.0 * special.gammaincinv(dof / 2.0, p))


def _use_as_view(use: Callable, robot: int, landmark_id: int, z, Q, t) -> Outcome:
    """`RobotView`'s update: the replay's `use` for this robot."""
    return use(robot, landmark_id, z, Q, t)


def _finish_chooser(s: _Robot) -> None:
    """Keep a robot's association counts and let its chooser go (it entered, or the run ended):
    the next one decides against the joint map."""
    if s.chooser is not None:
        s.association.update(dataclasses.asdict(s.chooser.finish().counts))
        s.chooser = None


def _body_rate(robot: _Robot, t: float) -> tuple[float, tuple[float, float]]:
    """rad/s and the body velocity (m/s) of the piece that ends at t (a time-stamp error moves
    the pose the sightings were taken from: `ekfslam.schedule.body_rate`'s)."""
    k = int(np.searchsorted(robot.breaks, t, side="left"))
    if k > 0 and robot.dt[k - 1] > 0:
        vx, vy, w = (robot.u[k - 1] / robot.dt[k - 1]).tolist()
        return w, (vx, vy)
    return 0.0, (0.0, 0.0)


def _pairs(points: Array) -> Iterable[tuple[Array, Array]]:
    for i in range(len(points)):
        for j in range(i + 1, len(points)):
            yield points[i], points[j]


def team_table(result: TeamResult) -> str:
    """A few lines: each robot's entry and counts (for a terminal)."""
    lines = []
    for robot in result.robots:
        track, entry = result.tracks[robot], result.entries.get(robot)
        accepted = track.landmarks.get("accepted", 0)
        seen = track.robots_seen.get("accepted", 0)
        where = entry.describe() if entry is not None else "never: it could not be placed"
        lines.append(
            f"robot {robot}: entered {where}; {accepted} landmark and {seen} robot sightings "
            f"accepted, seen by others {track.seen_by} times"
            + (f", {track.alone} sightings alone before entering" if track.alone else "")
        )
    return "\n".join(lines)


__all__ = ["ENTRY_LANDMARKS", "Entry", "RobotTrack", "TeamResult", "replay_team", "team_table"]
