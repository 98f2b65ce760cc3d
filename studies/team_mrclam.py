"""Five robots, one map: each MRCLAM dataset's robots alone, and together in one joint filter.

For every dataset: each robot replayed alone (`ekfslam.replay`, its documented defaults), its
map's eq. (17) error and, with Vicon, its trajectory error; the team through `replay_team`, with
the robots' sightings of one another and without them (the team then shares only its landmarks);
each robot's entry into the joint map (when, and how: its start, its own map's landmarks, or
its sightings with robots already placed); the joint map with the landmark ids hidden (jcbb, as
``run DATASET --robots all --hide-ids``: the robots' barcodes known); and the wall times, the
joint replay's the median of `REPEATS`. ``python -m studies team-mrclam``.

The joint filter takes no setting of its own chosen on these numbers: each robot keeps the noise
its single replay was tuned with (`ekfslam.logs.mrclam.defaults.MRCLAM_NOISE`), and the entry
rule's thresholds (`ekfslam.team.ENTRY_LANDMARKS` ...) were checked on Dataset 7 with its starts
withheld, then scored on Datasets 1, 2 and 4.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ekfslam.analysis import association as assoc
from ekfslam.analysis.alignment import align
from ekfslam.analysis.alignment_unlabelled import match_by_position
from ekfslam.analysis.evaluation import ate_rmse, interpolate_poses
from ekfslam.logs.mrclam.team import load_mrclam_team
from ekfslam.pipeline import replay
from ekfslam.team import TeamResult, replay_team

#: Joint replays timed per dataset; the median is reported (the machine's load varies).
REPEATS = 3


@dataclass(frozen=True)
class RobotRow:
    robot: int
    alone_map: float
    alone_ate: float | None
    joint_ate: float | None
    entry_s: float | None
    entry: str
    alone_seconds: float


@dataclass(frozen=True)
class DatasetRow:
    dataset: int
    robots: tuple[RobotRow, ...]
    joint_map: float
    joint_map_no_robot_sightings: float
    joint_seconds: float
    joint_map_hidden: float
    hidden_duplicates: int
    hidden_seconds: float

    @property
    def alone_mean(self) -> float:
        return float(np.mean([r.alone_map for r in self.robots]))

    @property
    def alone_best(self) -> float:
        return float(np.min([r.alone_map for r in self.robots]))


def track_ate(result: TeamResult, robot: int, groundtruth) -> float | None:
    """RMS position error of a robot's joint track against its Vicon (no alignment)."""
    if groundtruth is None or robot not in result.entries:
        return None
    track = result.tracks[robot]
    truth, inside = interpolate_poses(groundtruth, track.t)
    if not inside.any():
        return None
    error = track.pose[inside, :2] - truth[inside, :2]
    return float(np.sqrt(np.mean(np.sum(error**2, axis=1))))


def study_dataset(folder) -> DatasetRow:
    """Every robot of the dataset in `folder`, alone and together (the module docstring)."""
    team, report = load_mrclam_team(folder)
    dataset = int(next(iter(report.robots.values())).dataset)
    times = []
    for _ in range(REPEATS):
        started = time.perf_counter()
        joint = replay_team(team)
        times.append(time.perf_counter() - started)
    without = replay_team(team, robot_sightings=False)
    started = time.perf_counter()
    hidden = hidden_replay(team)
    hidden_seconds = time.perf_counter() - started
    hidden_map, found = assoc.score_team(team, hidden)
    rows = []
    for robot, run in team.runs.items():
        started = time.perf_counter()
        single = replay(run)
        seconds = time.perf_counter() - started
        entry = joint.entries.get(robot)
        rows.append(
            RobotRow(
                robot=robot,
                alone_map=align(single.landmarks, team.tag_map).mean_error,
                alone_ate=None if run.groundtruth is None else ate_rmse(single, run.groundtruth),
                joint_ate=track_ate(joint, robot, run.groundtruth),
                entry_s=None if entry is None else entry.seconds,
                entry="never" if entry is None else entry.how,
                alone_seconds=seconds,
            )
        )
    return DatasetRow(
        dataset=dataset,
        robots=tuple(rows),
        joint_map=align(joint.landmarks, team.tag_map).mean_error,
        joint_map_no_robot_sightings=align(without.landmarks, team.tag_map).mean_error,
        joint_seconds=float(np.median(times)),
        joint_map_hidden=align(hidden_map, team.tag_map).mean_error,
        hidden_duplicates=len(found.duplicates),
        hidden_seconds=hidden_seconds,
    )


def hidden_replay(team) -> TeamResult:
    """The team with the landmark ids hidden, as ``run DATASET --robots all --hide-ids`` replays
    it (`ekfslam.cli.team`): jcbb, each robot's deciding and mapping noise, maps matched by
    position for an entry from landmarks."""
    first = team.runs[team.robots[0]]
    return replay_team(
        team,
        {robot: assoc.association_noise(run) for robot, run in team.runs.items()},
        association=assoc.association_config(first, "jcbb"),
        match_maps=match_by_position,
        map_noise={robot: assoc.association_map_noise(run) for robot, run in team.runs.items()},
    )


def _yes(value: bool) -> str:
    return "yes" if value else "no"


def _m(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


def markdown(rows: list[DatasetRow]) -> str:
    """Per dataset: each robot alone (map, ATE), the joint map with and without the robots'
    sightings of one another, each robot's entry and ATE together, and the times."""
    lines = [
        "| dataset | robot | alone: map (m) | alone: ATE (m) | together: entry (s) | "
        "together: ATE (m) | alone: s |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        for r in row.robots:
            entry = "-" if r.entry_s is None else f"{r.entry_s:.1f} ({r.entry})"
            lines.append(
                f"| {row.dataset} | {r.robot} | {r.alone_map:.3f} | {_m(r.alone_ate)} | "
                f"{entry} | {_m(r.joint_ate)} | {r.alone_seconds:.2f} |"
            )
    lines += [
        "",
        "| dataset | alone: mean map (m) | alone: best (m) | joint map (m) | joint <= mean | "
        "joint < best | joint, no robot sightings (m) | joint, ids hidden (m) | "
        f"joint: s (median of {REPEATS}) | ids hidden: s |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in rows:
        lines.append(
            f"| {row.dataset} | {row.alone_mean:.3f} | {row.alone_best:.3f} | "
            f"{row.joint_map:.3f} | {_yes(row.joint_map <= row.alone_mean)} | "
            f"{_yes(row.joint_map < row.alone_best)} | "
            f"{row.joint_map_no_robot_sightings:.3f} | {row.joint_map_hidden:.3f} "
            f"({row.hidden_duplicates} duplicates) | {row.joint_seconds:.1f} | "
            f"{row.hidden_seconds:.1f} |"
        )
    return "\n".join(lines)
