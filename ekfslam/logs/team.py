"""A team's log: several robots' runs on one clock, and their sightings of one another.

Each robot's own run (`RunLog`: its controls, its landmark detections, its ground truth) stays
as a single replay reads it; what a team adds is `RobotSightings`: robot A's range and bearing to
robot B's centre, measured from A's centre and heading, as a landmark sighting is. A cooperative
filter predicts each robot with its own controls and corrects two poses at once with such a
sighting; the source of the log (MRCLAM, a simulator) does not matter to it.

`check_team` holds a team to what the filter assumes: robots numbered as the runs are, no robot
sighting itself, every sighting inside its observer's run and finite.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ekfslam import checks
from ekfslam.logs.runlog import RunLog

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RobotSightings:
    """Sightings of one robot by another, in time order.

    t : (K,) s, non-decreasing, on the runs' shared clock.
    observer, target : (K,) int, the robots' numbers (keys of `TeamLog.runs`), never equal.
    range : (K,) m, from the observer's centre to the target's.
    bearing : (K,) rad in [-π, π), from the observer's heading.
    """

    t: Array
    observer: NDArray[np.int64]
    target: NDArray[np.int64]
    range: Array
    bearing: Array

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def empty(cls) -> RobotSightings:
        """No sightings (a team whose robots never see one another)."""
        none = np.empty(0)
        return cls(none, none.astype(np.int64), none.astype(np.int64), none.copy(), none.copy())

    def pairs(self) -> dict[tuple[int, int], int]:
        """{(observer, target): how many sightings}, for reports."""
        keys, counts = np.unique(
            np.column_stack([self.observer, self.target]), axis=0, return_counts=True
        )
        return {(int(a), int(b)): int(n) for (a, b), n in zip(keys, counts, strict=True)}


@dataclass(frozen=True, eq=False)
class TeamLog:
    """Several robots' runs, sharing one clock and one arena, and their sightings of one another.

    name : a short label (``mrclam7-team``).
    runs : {robot number: its own run}; the runs' tag maps, where given, are the one arena's.
    sightings : the robots' sightings of one another (`RobotSightings`).
    """

    name: str
    runs: dict[int, RunLog]
    sightings: RobotSightings

    @property
    def robots(self) -> tuple[int, ...]:
        """The robots' numbers, in order."""
        return tuple(sorted(self.runs))

    @property
    def tag_map(self) -> dict | None:
        """The arena's true landmarks, as the first run with a tag map gives them, or None."""
        for robot in self.robots:
            if self.runs[robot].meta.tag_map is not None:
                return self.runs[robot].meta.tag_map
        return None

    @property
    def has_starts(self) -> bool:
        """Whether every robot's start is known (each run has its ground truth)."""
        return all(run.groundtruth is not None for run in self.runs.values())

    def span(self) -> tuple[float, float]:
        """(first, last) s of all the robots' controls."""
        starts = [float(run.controls.t[0]) for run in self.runs.values()]
        ends = [float(run.controls.t[-1]) for run in self.runs.values()]
        return min(starts), max(ends)


def check_team(team: TeamLog) -> None:
    """Refuse a team the cooperative filter cannot take, with one line saying what is wrong.

    Raises
    ------
    ValueError
        No runs; a robot number that is not a non-negative int; sightings of unequal lengths, out
        of time order, not finite, with a negative range or a bearing outside [-π, π); a robot
        sighting itself or a robot not in the team; a sighting outside its observer's controls.
    """
    checks.instance(
        team,
        TeamLog,
        "replay_team: team",
        "load one (ekfslam.logs.mrclam.team.load_mrclam_team, ekfslam.sim.team.simulate_team)",
    )
    if not team.runs:
        raise ValueError(f"team {team.name!r} has no robots")
    for robot in team.runs:
        if not isinstance(robot, int | np.integer) or isinstance(robot, bool) or robot < 0:
            raise ValueError(f"team {team.name!r}: robot number {robot!r} is not an int >= 0")
    s = team.sightings
    columns = {
        "t": s.t,
        "observer": s.observer,
        "target": s.target,
        "range": s.range,
        "bearing": s.bearing,
    }
    lengths = {name: np.shape(c) for name, c in columns.items()}
    if len({shape for shape in lengths.values()}) != 1 or len(lengths["t"]) != 1:
        raise ValueError(f"team {team.name!r}: robot sightings' columns differ: {lengths}")
    for name in ("t", "range", "bearing"):
        bad = np.flatnonzero(~np.isfinite(columns[name]))
        if bad.size:
            raise ValueError(f"team {team.name!r}: robot sighting {bad[0]}: {name} is not finite")
    problems = [
        (np.diff(s.t, prepend=-np.inf) < 0, "is earlier than the sighting before it"),
        (s.observer == s.target, "has a robot sighting itself"),
        (~np.isin(s.observer, team.robots), "has an observer that is not in the team"),
        (~np.isin(s.target, team.robots), "sees a robot that is not in the team"),
        (s.range < 0, "has a negative range"),
        ((s.bearing < -np.pi) | (s.bearing >= np.pi), "has a bearing outside [-pi, pi)"),
    ]
    for robot, run in team.runs.items():
        mine = s.observer == robot
        outside = (s.t < run.controls.t[0]) | (s.t > run.controls.t[-1])
        problems.append((mine & outside, f"is outside robot {robot}'s controls"))
    for mask, what in problems:
        bad = np.flatnonzero(mask)
        if bad.size:
            k = int(bad[0])
            raise ValueError(
                f"team {team.name!r}: robot sighting {k} (t {float(s.t[k]):g} s, robot "
                f"{int(s.observer[k])} sees {int(s.target[k])}) {what}"
            )
