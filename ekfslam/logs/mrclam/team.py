"""Read several robots of an MRCLAM dataset as one team (`ekfslam.logs.team.TeamLog`).

MRCLAM is a *cooperative* dataset: the five robots drive the arena at once, on one clock, and
each camera reads the other robots' barcodes as well as the landmarks'. `load_mrclam` keeps a
robot's landmark sightings and counts its sightings of robots as dropped; here those become the
team's `RobotSightings` (observer, target, range, bearing), measured, as a landmark's, from the
observer's centre and heading to the barcode on top of the target robot, at its centre.

What a team leaves out is counted too (`TeamLoadReport`): a sighting of a robot that is not in
the chosen team, and one beyond the range cut.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ekfslam.errors import InputError
from ekfslam.logs.mrclam.checks import DEFAULT_MAX_RANGE
from ekfslam.logs.mrclam.load import ROBOTS, load_robot
from ekfslam.logs.mrclam.report import MrclamLoadReport
from ekfslam.logs.team import RobotSightings, TeamLog


@dataclass(frozen=True)
class TeamLoadReport:
    """What `load_mrclam_team` read: each robot's own report, and the robot sightings it kept.

    robots : {robot: its `MrclamLoadReport`} (whose ``robot_sightings_dropped`` counts every
        sighting of a robot in its file, kept here or not).
    robot_sightings_kept : {(observer, target): count} of the team's sightings of one another.
    outside_team : sightings of a robot that is not in the team, dropped.
    beyond_range : sightings of a team robot beyond the range cut, dropped.
    """

    robots: dict[int, MrclamLoadReport]
    robot_sightings_kept: dict[tuple[int, int], int]
    outside_team: int
    beyond_range: int

    @property
    def kept(self) -> int:
        """How many robot sightings the team keeps."""
        return sum(self.robot_sightings_kept.values())

    def as_dict(self) -> dict:
        """JSON-ready: each robot's report, and the robot sightings kept and dropped."""
        kept = {f"{a}->{b}": n for (a, b), n in sorted(self.robot_sightings_kept.items())}
        return {
            "robots": {str(r): report.as_dict() for r, report in self.robots.items()},
            "robot_sightings": {
                "kept": self.kept,
                "by_pair": kept,
                "dropped": {
                    "outside_team": {"count": self.outside_team, "reason": _OUTSIDE_WHY},
                    "beyond_range": {"count": self.beyond_range, "reason": _FAR_WHY},
                },
            },
        }

    def summary(self) -> str:
        """A few lines for a terminal: the team's robot sightings, then each robot's report."""
        head = (
            f"team of robots {', '.join(map(str, self.robots))}: {self.kept} sightings of one "
            f"another kept; dropped {self.outside_team} of robots outside the team, "
            f"{self.beyond_range} beyond range"
        )
        return "\n".join([head, *(report.summary() for report in self.robots.values())])


_OUTSIDE_WHY = "the robot seen is not in the team"
_FAR_WHY = "beyond the camera's reliable range"


def load_mrclam_team(
    dataset_dir: str | Path,
    robots: Iterable[int] = ROBOTS,
    max_range: float | None = DEFAULT_MAX_RANGE,
    fix_barcode_swap: bool = True,
) -> tuple[TeamLog, TeamLoadReport]:
    """Load robots `robots` (some of 1-5, at least one) of an MRCLAM dataset folder as a team.

    Each robot's run is exactly `load_mrclam`'s (its controls, landmark detections, ground truth
    and start); the team adds the sightings among the chosen robots, merged in time order (ties
    in observer order, then in file order).

    Raises
    ------
    InputError
        No robots, a robot outside 1-5 or named twice, or what `load_mrclam` refuses.
    """
    folder = Path(dataset_dir)
    chosen = list(robots)
    if not chosen:
        raise InputError(folder, None, "a team needs at least one robot (1 to 5)")
    twice = sorted({r for r in chosen if chosen.count(r) > 1})
    if twice:
        raise InputError(folder, None, f"robot {twice[0]} is named twice in the team")
    runs, reports, rows = {}, {}, []
    for robot in sorted(chosen):
        run, report, seen = load_robot(folder, robot, max_range, fix_barcode_swap)
        runs[int(robot)], reports[int(robot)] = run, report
        rows.append(np.column_stack([seen, np.full(len(seen), float(robot))]))
    table = np.concatenate(rows)  # t, target, range, bearing, observer
    inside = np.isin(table[:, 1].astype(np.int64), list(runs))
    beyond = sum(r.robot_sightings_dropped for r in reports.values()) - len(table)
    table = table[inside]
    table = table[np.argsort(table[:, 0], kind="stable")]  # observers in order: stable ties
    sightings = RobotSightings(
        t=table[:, 0].copy(),
        observer=table[:, 4].astype(np.int64),
        target=table[:, 1].astype(np.int64),
        range=table[:, 2].copy(),
        bearing=table[:, 3].copy(),
    )
    dataset = next(iter(reports.values())).dataset
    team = TeamLog(name=f"mrclam{dataset}-team", runs=runs, sightings=sightings)
    report = TeamLoadReport(
        robots=reports,
        robot_sightings_kept=sightings.pairs() if len(sightings) else {},
        outside_team=int(np.count_nonzero(~inside)),
        beyond_range=int(beyond),
    )
    return team, report
