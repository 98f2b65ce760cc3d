"""The team log: MRCLAM's five robots with their sightings of one another, and `check_team`.

The MRCLAM counts are computed here from the raw files with plain Python (string splitting),
independently of the loader; `check_team` is held to generated teams, each corrupted one way.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ekfslam.errors import InputError
from ekfslam.logs.mrclam.checks import DEFAULT_MAX_RANGE
from ekfslam.logs.mrclam.load import load_mrclam
from ekfslam.logs.mrclam.team import load_mrclam_team
from ekfslam.logs.runlog import Controls, Detections, RunLog, RunMeta
from ekfslam.logs.team import RobotSightings, TeamLog, check_team


def _raw_robot_sightings(folder, robot):
    """(t, subject, range, bearing) of each sighting of a robot in RobotN_Measurement.dat."""
    barcodes = {}
    for line in (folder / "Barcodes.dat").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            subject, barcode = line.split()
            barcodes[int(barcode)] = int(subject)
    rows = []
    for line in (folder / f"Robot{robot}_Measurement.dat").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            t, barcode, r, b = line.split()
            subject = barcodes.get(int(barcode), 0)
            if 1 <= subject <= 5:
                rows.append((float(t), subject, float(r), float(b)))
    return rows


@pytest.mark.shared_data
def test_mrclam_team_keeps_every_robot_sighting_of_the_files(mrclam7):
    team, report = load_mrclam_team(mrclam7)
    check_team(team)
    assert team.robots == (1, 2, 3, 4, 5) and team.has_starts
    expected = {}
    for robot in team.robots:
        for _t, target, r, _ in _raw_robot_sightings(mrclam7, robot):
            if DEFAULT_MAX_RANGE is None or r <= DEFAULT_MAX_RANGE:
                expected[(robot, target)] = expected.get((robot, target), 0) + 1
    assert report.robot_sightings_kept == expected
    assert report.kept == len(team.sightings) == sum(expected.values()) > 4000
    dropped = sum(r.robot_sightings_dropped for r in report.robots.values())
    assert report.kept + report.outside_team + report.beyond_range == dropped
    assert np.all(np.diff(team.sightings.t) >= 0)


@pytest.mark.shared_data
def test_mrclam_team_sightings_are_the_files_rows(mrclam7):
    team, _ = load_mrclam_team(mrclam7, robots=[5, 2])
    s = team.sightings
    for robot in (2, 5):
        raw = [row for row in _raw_robot_sightings(mrclam7, robot) if row[1] in (2, 5)]
        mine = s.observer == robot
        assert np.count_nonzero(mine) == len(raw)
        got = sorted(zip(s.t[mine], s.target[mine], s.range[mine], s.bearing[mine], strict=True))
        for (t, target, r, b), (t2, target2, r2, b2) in zip(got, sorted(raw), strict=True):
            assert (t, target, r) == (t2, target2, r2)
            assert math.isclose(b, math.remainder(b2, 2 * math.pi), abs_tol=1e-15)


@pytest.mark.shared_data
def test_mrclam_team_runs_are_the_single_robot_runs(mrclam7):
    team, report = load_mrclam_team(mrclam7, robots=[3, 1])
    assert team.robots == (1, 3)
    assert report.outside_team > 0  # robots 1 and 3 see 2, 4 and 5 too
    for robot in team.robots:
        alone, alone_report = load_mrclam(mrclam7, robot)
        run = team.runs[robot]
        assert np.array_equal(run.controls.values, alone.controls.values)
        assert np.array_equal(run.detections.tag_id, alone.detections.tag_id)
        assert np.array_equal(run.meta.nominal_start, alone.meta.nominal_start)
        assert report.robots[robot] == alone_report
    assert team.tag_map is not None and len(team.tag_map) == 15


@pytest.mark.shared_data
@pytest.mark.parametrize(
    ("robots", "says"),
    [([], "at least one robot"), ([2, 2], "robot 2 is named twice"), ([1, 6], "robot must be")],
)
def test_mrclam_team_refuses_a_bad_choice_of_robots(mrclam7, robots, says):
    with pytest.raises(InputError, match=says):
        load_mrclam_team(mrclam7, robots=robots)


# ------------------------------------------------------------------------- check_team
def _team(n_robots: int, sightings: RobotSightings) -> TeamLog:
    runs = {}
    for robot in range(1, n_robots + 1):
        meta = RunMeta(name=f"r{robot}", source="simulated", nominal_start=np.zeros(3))
        controls = Controls(t=np.array([0.0, 10.0]), kind="twist", values=np.zeros((2, 3)))
        none = Detections(np.empty(0), np.empty(0, np.int64), np.empty(0), np.empty(0))
        runs[robot] = RunLog(meta=meta, controls=controls, detections=none)
    return TeamLog(name="generated", runs=runs, sightings=sightings)


@st.composite
def teams(draw):
    n = draw(st.integers(2, 5))
    k = draw(st.integers(1, 30))
    pair = st.tuples(st.integers(1, n), st.integers(1, n)).filter(lambda p: p[0] != p[1])
    pairs = np.array(draw(st.lists(pair, min_size=k, max_size=k)), dtype=np.int64)
    t = np.sort(np.array(draw(st.lists(st.floats(0, 10), min_size=k, max_size=k))))
    r = np.array(draw(st.lists(st.floats(0, 5), min_size=k, max_size=k)))
    b = np.array(
        draw(st.lists(st.floats(-math.pi, math.pi, exclude_max=True), min_size=k, max_size=k))
    )
    return _team(n, RobotSightings(t, pairs[:, 0], pairs[:, 1], r, b))


CORRUPTIONS = {
    "is earlier than the sighting before it": lambda s, k: s.t.__setitem__(k, s.t[k - 1] - 1),
    "has a robot sighting itself": lambda s, k: s.target.__setitem__(k, s.observer[k]),
    "sees a robot that is not in the team": lambda s, k: s.target.__setitem__(k, 9),
    "has a negative range": lambda s, k: s.range.__setitem__(k, -0.1),
    "has a bearing outside": lambda s, k: s.bearing.__setitem__(k, math.pi),
    "outside robot": lambda s, k: s.t.__setitem__(slice(k, None), 11.0),
    "is not finite": lambda s, k: s.range.__setitem__(k, math.nan),
}


@given(teams())
def test_check_team_takes_a_well_formed_team(team):
    check_team(team)


@given(teams(), st.sampled_from(sorted(CORRUPTIONS)), st.data())
def test_check_team_names_the_first_bad_sighting(team, what, data):
    s = team.sightings
    first = 1 if what.startswith("is earlier") else 0
    if len(s) <= first:
        return
    k = data.draw(st.integers(first, len(s) - 1), label="k")
    CORRUPTIONS[what](s, k)
    with pytest.raises(ValueError, match=what) as refused:
        check_team(team)
    message = str(refused.value)
    assert "\n" not in message
    if what != "outside robot":  # there: the first sighting of the robot that ends first
        assert f"robot sighting {k} " in message or f"robot sighting {k}:" in message


def test_check_team_refuses_unequal_columns():
    s = RobotSightings(np.zeros(2), np.array([1, 2]), np.array([2]), np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match="columns differ"):
        check_team(_team(2, s))


def test_an_empty_team_and_no_sightings():
    with pytest.raises(ValueError, match="has no robots"):
        check_team(TeamLog(name="none", runs={}, sightings=RobotSightings.empty()))
    check_team(_team(3, RobotSightings.empty()))
