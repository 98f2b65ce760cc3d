"""`run_from_arrays`: a run from arrays in memory is the run ``read_run`` gives, and a bad array is
one line naming the argument and the row."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import ekfslam
from ekfslam.core.kinematics import MecanumGeometry
from ekfslam.errors import InputError
from ekfslam.logs.arrays import run_from_arrays
from ekfslam.logs.runlog import read_run, write_run

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


def _columns(path: Path) -> np.ndarray:
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def _from_files(folder: Path, **meta) -> ekfslam.RunLog:
    """The run in `folder`, rebuilt from its CSV files read as plain float arrays."""
    c = _columns(folder / "controls.csv")
    d = _columns(folder / "detections.csv")
    g = _columns(folder / "groundtruth.csv")
    return run_from_arrays(
        controls_t=c[:, 0],
        wheels=c[:, 1:],
        detections_t=d[:, 0],
        tag_id=d[:, 1],  # floats from loadtxt: accepted when whole
        range=d[:, 2],
        bearing=d[:, 3],
        groundtruth_t=g[:, 0],
        groundtruth=g[:, 1:],
        **meta,
    )


def test_the_facade_names_it():
    assert ekfslam.run_from_arrays is run_from_arrays
    assert "run_from_arrays" in ekfslam.__all__


def test_a_shipped_run_from_its_arrays_replays_as_read_run_does():
    folder = RUNS / "octagon-2laps"
    read = read_run(folder)
    built = _from_files(
        folder,
        start=read.meta.nominal_start,
        robot=read.meta.robot,
        tag_map=read.meta.tag_map,
        name="octagon-2laps",
    )
    assert built.meta.source == "recorded" and built.controls.kind == "wheels"
    assert built.detections.tag_id.dtype == np.int64
    for name in ("t", "tag_id", "range", "bearing"):
        assert np.array_equal(getattr(built.detections, name), getattr(read.detections, name))
    ours, theirs = ekfslam.replay(built), ekfslam.replay(read)
    assert ours.landmarks.keys() == theirs.landmarks.keys() and len(ours.landmarks) == 8
    for tag, xy in theirs.landmarks.items():
        assert np.array_equal(ours.landmarks[tag], xy)  # bit for bit: the same arithmetic
    error = ekfslam.summarize(built, ours).alignment.mean_error
    assert error == ekfslam.summarize(read, theirs).alignment.mean_error
    assert 0.003 < error < 0.01  # the README's octagon row: about 5 mm


def test_twist_controls_give_the_same_map_as_the_wheels_they_came_from():
    folder = RUNS / "square-2laps"
    read = read_run(folder)
    c, d = _columns(folder / "controls.csv"), _columns(folder / "detections.csv")
    run = run_from_arrays(
        controls_t=c[:, 0],
        twist=ekfslam.wheels_to_twist(c[:, 1:], read.meta.robot),
        detections_t=d[:, 0],
        tag_id=d[:, 1].astype(int),
        range=d[:, 2],
        bearing=d[:, 3],
        start=read.meta.nominal_start,
    )
    assert run.meta.tag_map is None and run.groundtruth is None
    ours, theirs = ekfslam.replay(run), ekfslam.replay(read)
    for tag, xy in theirs.landmarks.items():
        np.testing.assert_allclose(ours.landmarks[tag], xy, atol=1e-12)


def _small(**changes) -> dict:
    """A valid set of arguments: three control rows, two sightings."""
    args = {
        "controls_t": [0.0, 0.5, 1.0],
        "twist": [[0.1, 0.0, 0.0], [0.2, 0.0, 0.1], [0.0, 0.0, 0.0]],
        "detections_t": [0.2, 0.6],
        "tag_id": [3, 4],
        "range": [1.2, 0.8],
        "bearing": [0.3, -0.5],
    }
    return args | changes


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"controls_t": [0.0, 0.6, 0.5]}, "controls[2]: time 0.5 s is earlier than the previous"),
        ({"range": [1.2, -0.8]}, "detections[1]: negative range -0.8 m (a range is >= 0)"),
        ({"bearing": [0.3, 30.0]}, "detections[1]: bearing 30.0 rad is outside [-pi, pi]"),
        ({"detections_t": [0.2, float("nan")]}, "detections[1]: t is nan"),
        (
            {"twist": [[0.1, 0.0], [0.2, 0.0], [0.0, 0.0]]},
            "twist: has shape (3, 2), expected (3, 3)",
        ),
        ({"range": [1.2]}, "range: has shape (1,), expected (2,)"),
        ({"tag_id": [3, 4.5]}, "tag_id[1]: 4.5 is not a whole tag id"),
        ({"tag_id": ["a", "b"]}, "tag_id: must be numbers"),
        (
            {"wheels": [[1.0] * 4] * 3},
            "run_from_arrays: give the controls as twist= or wheels=, once",
        ),
        ({"twist": None}, "run_from_arrays: give the controls as twist= or wheels=, once"),
        ({"twist": None, "wheels": [[1.0] * 4] * 3}, "wheels: wheel speeds need robot="),
        ({"controls_t": [], "twist": np.zeros((0, 3))}, "controls[0]: no controls: controls_t is"),
        ({"start": [0.0, 0.0]}, "start: has shape (2,), expected (3,)"),
        ({"start": [0.0, 0.0, 7.0]}, "run_from_arrays: nominal_start: heading 7.0 rad"),
        ({"tag_map": {3: [0.0, 1.0]}}, "detections[1]: tag 4 is not in tag_map (known: 3)"),
        ({"tag_map": {"3": [0.0, 1.0]}}, "tag_map: tag id '3' is not an integer"),
        ({"groundtruth_t": [0.0]}, "groundtruth: give groundtruth_t and groundtruth together"),
        (
            {"groundtruth_t": [0.0, 1.0], "groundtruth": [[0.0, 0.0, 0.0], [0.0, 0.0, np.inf]]},
            "groundtruth[1]: theta is inf",
        ),
        (
            {"detections_t": [0.2, 1.7e9]},
            "detections[1]: time 1700000000.0 s is more than 1 s outside controls's time span",
        ),
    ],
)
def test_a_bad_array_is_one_line_naming_the_argument_and_row(changes, message):
    with pytest.raises(InputError) as caught:
        run_from_arrays(**_small(**changes))
    text = str(caught.value)
    assert text.startswith(message), text
    assert "\n" not in text and ".csv" not in text and "run.json" not in text


def test_no_sightings_and_wheels_with_a_robot_are_a_run():
    run = run_from_arrays(
        **_small(detections_t=[], tag_id=[], range=[], bearing=[], twist=None),
        wheels=np.ones((3, 4)),
        robot=MecanumGeometry(),
    )
    assert len(run.detections.t) == 0 and run.detections.tag_id.dtype == np.int64
    assert np.allclose(run.control_twist()[:, 0], 0.03)  # r ω = 0.03 m/s forward, nothing else
    assert ekfslam.replay(run).landmarks == {}


times = st.lists(st.floats(0, 100, allow_nan=False), min_size=1, max_size=30).map(sorted)


@settings(max_examples=40, deadline=None)
@given(
    controls_t=times,
    sightings=st.lists(
        st.tuples(
            st.floats(0, 100),
            st.integers(0, 2**40),
            st.floats(0, 50),
            st.floats(-3.14159, 3.14159),
        ),
        max_size=30,
    ),
    data=st.data(),
)
def test_what_it_builds_is_what_the_run_format_writes_and_reads_back(
    tmp_path_factory, controls_t, sightings, data
):
    """Any valid arrays: the run written and read back is the same run, to the bit."""
    twist = data.draw(
        st.lists(
            st.tuples(*[st.floats(-5, 5)] * 3),
            min_size=len(controls_t),
            max_size=len(controls_t),
        )
    )
    sightings = sorted(sightings)
    span = max(controls_t) - min(controls_t)
    margin = max(1.0, 0.1 * span)
    inside = [s for s in sightings if min(controls_t) <= s[0] <= max(controls_t)]
    if 2 * len(inside) < len(sightings) or any(
        not min(controls_t) - margin <= s[0] <= max(controls_t) + margin for s in sightings
    ):
        sightings = inside  # the clocks' rule is tested above; keep the run on one clock
    run = run_from_arrays(
        controls_t=controls_t,
        twist=twist,
        detections_t=[s[0] for s in sightings],
        tag_id=[s[1] for s in sightings],
        range=[s[2] for s in sightings],
        bearing=[s[3] for s in sightings],
        start=(0.1, -0.2, 0.3),
    )
    back = read_run(write_run(run, tmp_path_factory.mktemp("run")))
    assert np.array_equal(back.controls.t, np.asarray(controls_t, dtype=float))
    assert np.array_equal(back.controls.values, np.asarray(twist, dtype=float).reshape(-1, 3))
    for name in ("t", "tag_id", "range", "bearing"):
        assert np.array_equal(getattr(back.detections, name), getattr(run.detections, name))


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 20), data=st.data())
def test_a_nan_anywhere_is_named_by_its_argument_and_row(n, data):
    row = data.draw(st.integers(0, n - 1))
    column = data.draw(st.sampled_from(["vx", "vy", "wz"]))
    twist = np.zeros((n, 3))
    twist[row, ["vx", "vy", "wz"].index(column)] = np.nan
    with pytest.raises(InputError, match=rf"^controls\[{row}\]: {column} is nan"):
        run_from_arrays(
            controls_t=np.arange(n, dtype=float),
            twist=twist,
            detections_t=[],
            tag_id=[],
            range=[],
            bearing=[],
        )
