"""`run_from_arrays`: a run from arrays in memory is the run ``read_run`` gives, and a bad array is
one line naming the array and the row."""

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


def _table(path: Path) -> np.ndarray:
    """A run file's columns as plain floats, as a user's own log would come."""
    return np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def test_the_facade_names_it():
    assert ekfslam.run_from_arrays is run_from_arrays
    assert "run_from_arrays" in ekfslam.__all__


def test_a_shipped_run_from_its_arrays_replays_as_read_run_does():
    folder = RUNS / "octagon-2laps"
    read = read_run(folder)
    built = run_from_arrays(
        controls=_table(folder / "controls.csv"),  # t, w1..w4
        detections=_table(folder / "detections.csv"),  # tag ids as floats: accepted when whole
        groundtruth=_table(folder / "groundtruth.csv"),
        start=read.meta.nominal_start,
        robot=read.meta.robot,
        tag_map=read.meta.tag_map,
    )
    assert built.meta.source == "recorded" and built.controls.kind == "wheels"
    assert built.detections.tag_id.dtype == np.int64 and len(built.detections.t) == 622
    for name in ("t", "tag_id", "range", "bearing"):
        assert np.array_equal(getattr(built.detections, name), getattr(read.detections, name))
    assert np.array_equal(built.groundtruth.pose, read.groundtruth.pose)
    ours, theirs = ekfslam.replay(built), ekfslam.replay(read)
    assert ours.landmarks.keys() == theirs.landmarks.keys() and len(ours.landmarks) == 8
    for tag, xy in theirs.landmarks.items():
        assert np.array_equal(ours.landmarks[tag], xy)  # bit for bit: the same arithmetic
    error = ekfslam.summarize(built, ours).alignment.mean_error
    assert error == ekfslam.summarize(read, theirs).alignment.mean_error
    assert 0.003 < error < 0.008  # the octagon's Table 1 row: about 5 mm


def test_twist_controls_give_the_map_of_the_wheels_they_came_from():
    folder = RUNS / "square-2laps"
    read = read_run(folder)
    wheels = _table(folder / "controls.csv")
    twist = ekfslam.wheels_to_twist(wheels[:, 1:], read.meta.robot)
    run = run_from_arrays(
        controls=np.column_stack([wheels[:, 0], twist]),
        detections=_table(folder / "detections.csv"),
        start=read.meta.nominal_start,
    )
    assert run.controls.kind == "twist" and run.meta.tag_map is None and run.groundtruth is None
    ours, theirs = ekfslam.replay(run), ekfslam.replay(read)
    assert ours.landmarks.keys() == theirs.landmarks.keys()
    for tag, xy in theirs.landmarks.items():
        np.testing.assert_allclose(ours.landmarks[tag], xy, atol=1e-12)


def _small(**changes) -> dict:
    """Valid arguments: three rows of twist, two sightings."""
    args = {
        "controls": [[0.0, 0.1, 0.0, 0.0], [0.5, 0.2, 0.0, 0.1], [1.0, 0.0, 0.0, 0.0]],
        "detections": [[0.2, 3, 1.2, 0.3], [0.6, 4, 0.8, -0.5]],
    }
    return args | changes


def _with(array: list, row: int, column: int, value: float) -> np.ndarray:
    table = np.array(array, dtype=float)
    table[row, column] = value
    return table


C, D = _small()["controls"], _small()["detections"]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"controls": _with(C, 2, 0, 0.4)}, "controls[2]: time 0.4 s is earlier than the previous"),
        ({"controls": _with(C, 1, 3, np.nan)}, "controls[1]: wz is nan: every value must be"),
        ({"detections": _with(D, 1, 2, -0.8)}, "detections[1]: negative range -0.8 m (a range is"),
        ({"detections": _with(D, 1, 3, 30.0)}, "detections[1]: bearing 30.0 rad is outside [-pi,"),
        ({"detections": _with(D, 0, 0, np.inf)}, "detections[0]: t is inf"),
        ({"detections": _with(D, 1, 1, 4.5)}, "detections[1]: tag_id 4.5 is not a whole id"),
        ({"detections": [[0.2, 3, 1.2]]}, "detections: has shape (1, 3), expected (N, 4)"),
        ({"detections": "abc"}, "detections: must be numbers"),
        ({"controls": [[0.0, 1.0, 2.0]]}, "controls: has 3 columns: 4 are t, vx, vy, wz and 5"),
        ({"controls": [0.0, 1.0, 2.0, 3.0]}, "controls: has shape (4,), expected (N, columns)"),
        ({"controls": np.ones((3, 5))}, "controls: 5 columns are wheel speeds, which need robot="),
        ({"controls": np.zeros((0, 4))}, "controls[0]: no controls: the array has no rows"),
        ({"start": [0.0, 0.0]}, "start: has shape (2,), expected (3,): x, y, theta"),
        ({"start": [0.0, 0.0, 7.0]}, "run_from_arrays: nominal_start: heading 7.0 rad"),
        ({"tag_map": {3: [0.0, 1.0]}}, "detections[1]: tag 4 is not in tag_map (known: 3)"),
        ({"tag_map": {"3": [0.0, 1.0]}}, "tag_map: tag id '3' is not an integer"),
        ({"tag_map": {3: [0.0, 1.0, 2.0]}}, "tag_map[3]: has shape (3,), expected (2,)"),
        ({"groundtruth": [[0.0, 0, 0, 0], [1.0, 0, 0, np.inf]]}, "groundtruth[1]: theta is inf"),
        (
            {"detections": _with(D, 1, 0, 1.7e9)},
            "detections[1]: time 1700000000.0 s is more than 1 s outside controls's time span",
        ),
    ],
)
def test_a_bad_array_is_one_line_naming_the_array_and_row(changes, message):
    with pytest.raises(InputError) as caught:
        run_from_arrays(**_small(**changes))
    text = str(caught.value)
    assert text.startswith(message), text
    assert "\n" not in text and ".csv" not in text and "run.json" not in text


def test_no_sightings_and_wheels_with_a_robot_are_a_run():
    run = run_from_arrays(
        controls=np.column_stack([[0.0, 1.0, 2.0], np.ones((3, 4))]),
        detections=[],
        robot=MecanumGeometry(),
    )
    assert len(run.detections.t) == 0 and run.detections.tag_id.dtype == np.int64
    np.testing.assert_allclose(run.control_twist(), [[0.03, 0.0, 0.0]] * 3)  # r ω forward
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
            st.tuples(*[st.floats(-5, 5)] * 3), min_size=len(controls_t), max_size=len(controls_t)
        )
    )
    start, end = min(controls_t), max(controls_t)
    sightings = sorted(s for s in sightings if start <= s[0] <= end)  # one clock: tested above
    run = run_from_arrays(
        controls=[[t, *v] for t, v in zip(controls_t, twist, strict=True)],
        detections=np.array(sightings, dtype=float).reshape(-1, 4),
        start=(0.1, -0.2, 0.3),
    )
    back = read_run(write_run(run, tmp_path_factory.mktemp("run")))
    assert np.array_equal(back.controls.t, np.asarray(controls_t, dtype=float))
    assert np.array_equal(back.controls.values, np.asarray(twist, dtype=float).reshape(-1, 3))
    assert back.detections.tag_id.tolist() == [s[1] for s in sightings]
    for name in ("t", "range", "bearing"):
        assert np.array_equal(getattr(back.detections, name), getattr(run.detections, name))


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 20), data=st.data())
def test_a_nan_anywhere_is_named_by_its_array_row_and_column(n, data):
    row = data.draw(st.integers(0, n - 1))
    column = data.draw(st.sampled_from(["t", "vx", "vy", "wz"]))
    controls = np.column_stack([np.arange(n, dtype=float), np.zeros((n, 3))])
    controls[row, ["t", "vx", "vy", "wz"].index(column)] = np.nan
    with pytest.raises(InputError, match=rf"^controls\[{row}\]: {column} is nan"):
        run_from_arrays(controls=controls, detections=[])
