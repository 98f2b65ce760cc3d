"""The run-log format: exact round trips, and one precise error for every malformed input."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from ekfslam.core.kinematics import MecanumGeometry
from ekfslam.errors import InputError
from ekfslam.logs.csvtable import csv_text, read_table
from ekfslam.logs.runlog import (
    Controls,
    Detections,
    GroundTruth,
    RunLog,
    RunMeta,
    read_run,
    validate_run,
    write_run,
)

# ---------------------------------------------------------------------------------------------
# Hand-written run folders

CONTROLS = "t,vx,vy,wz\n0.0,0.1,0.0,0.0\n0.5,0.2,0.0,0.1\n1.0,0.2,0.0,0.1\n"
WHEELS = "t,w1,w2,w3,w4\n0.0,1.0,1.0,1.0,1.0\n0.5,-1.0,1.0,-1.0,1.0\n"
DETECTIONS = "t,tag_id,range,bearing\n0.1,1,1.2,0.3\n0.1,2,0.8,-0.5\n0.6,1,1.1,0.31\n"
GROUNDTRUTH = "t,x,y,theta\n0.0,-0.375,-0.375,0.0\n1.0,-0.2,-0.375,0.05\n"
ROBOT = {"type": "mecanum", "wheel_radius": 0.03, "lx": 0.068, "ly": 0.054}


def run_doc(**changes: object) -> dict:
    doc = {
        "format": "ekfslam-run",
        "format_version": 1,
        "name": "demo",
        "source": "recorded",
        "units": {"length": "m", "angle": "rad", "time": "s"},
        "rates": {"controls_hz": 2.0, "camera_hz": None},
        "robot": ROBOT,
        "camera_mounting": {"x": 0.05, "y": 0.0, "yaw": 0.0},
        "nominal_start": [-0.375, -0.375, 0.0],
        "tag_map": None,
        "simulation": None,
    }
    doc.update(changes)
    return {k: v for k, v in doc.items() if v is not _DROP}


_DROP = object()


def make_run(
    folder: Path,
    *,
    run_json: str | None = None,
    controls: str | None = CONTROLS,
    detections: str | None = DETECTIONS,
    groundtruth: str | None = None,
    **changes: object,
) -> Path:
    """Write a run folder from text; None leaves a file out."""
    folder.mkdir(parents=True, exist_ok=True)
    texts = {
        "run.json": run_json if run_json is not None else json.dumps(run_doc(**changes), indent=2),
        "controls.csv": controls,
        "detections.csv": detections,
        "groundtruth.csv": groundtruth,
    }
    for name, text in texts.items():
        if text is not None:
            (folder / name).write_text(text, encoding="utf-8", newline="")
    return folder


def error_of(folder: Path) -> InputError:
    with pytest.raises(InputError) as info:
        read_run(folder)
    return info.value


def line_with(text: str, fragment: str, nth: int = 0) -> int:
    """1-based line number of the nth line of `text` containing `fragment`."""
    return [i for i, line in enumerate(text.splitlines(), 1) if fragment in line][nth]


# ---------------------------------------------------------------------------------------------
# Reading good input


def test_reads_hand_written_run(tmp_path: Path) -> None:
    run = read_run(make_run(tmp_path, groundtruth=GROUNDTRUTH))
    assert run.controls.kind == "twist"
    assert np.array_equal(run.controls.t, [0.0, 0.5, 1.0])
    assert np.array_equal(run.controls.values[1], [0.2, 0.0, 0.1])
    assert run.detections.tag_id.dtype == np.int64
    assert run.detections.tag_id.tolist() == [1, 2, 1]
    assert np.array_equal(run.detections.bearing, [0.3, -0.5, 0.31])
    assert np.array_equal(run.groundtruth.pose[1], [-0.2, -0.375, 0.05])
    assert run.meta.robot == MecanumGeometry(0.03, 0.068, 0.054)
    assert run.meta.control_rate_hz == 2.0 and run.meta.camera_rate_hz is None
    assert np.array_equal(run.meta.camera_mounting, [0.05, 0.0, 0.0])
    assert run.meta.tag_map is None and run.groundtruth.t.tolist() == [0.0, 1.0]


def test_groundtruth_is_optional_and_detections_may_be_empty(tmp_path: Path) -> None:
    run = read_run(make_run(tmp_path, detections="t,tag_id,range,bearing\n"))
    assert run.groundtruth is None
    assert run.detections.t.shape == (0,) and run.detections.tag_id.dtype == np.int64
    assert run.detections.range.shape == (0,) and run.detections.bearing.shape == (0,)


def test_wheel_controls_give_the_mecanum_twist(tmp_path: Path) -> None:
    run = read_run(make_run(tmp_path, controls=WHEELS))
    assert run.controls.kind == "wheels" and run.controls.values.shape == (2, 4)
    twist = run.control_twist()
    # all wheels at 1 rad/s: forward at r; the (-1, 1, -1, 1) pattern: pure turn at r / (lx + ly)
    np.testing.assert_allclose(twist[0], [0.03, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(twist[1], [0.0, 0.0, 0.03 / 0.122], atol=1e-15)
    with pytest.raises(ValueError, match="geometry"):
        run.controls.twist()
    twist_run = read_run(make_run(tmp_path / "b"))
    assert np.array_equal(twist_run.controls.twist(), twist_run.controls.values)


def _decorated(text: str) -> str:
    """The same table with a BOM, CRLF endings, padded fields and trailing blank lines."""
    lines = [" , ".join(f" {f}\t" for f in line.split(",")) for line in text.splitlines()]
    return "\ufeff" + "\r\n".join(lines) + "\r\n\r\n  \r\n"


def test_bom_crlf_whitespace_and_trailing_blank_lines_read_the_same(tmp_path: Path) -> None:
    kwargs = {"controls": WHEELS, "detections": DETECTIONS, "groundtruth": GROUNDTRUTH}
    plain = read_run(make_run(tmp_path / "plain", tag_map={"1": [1, 2], "2": [3, 4]}, **kwargs))
    json_text = json.dumps(run_doc(tag_map={"1": [1, 2], "2": [3, 4]}), indent=2)
    fancy_json = "\ufeff" + json_text.replace("\n", "\r\n") + "\r\n\r\n"
    fancy = read_run(
        make_run(
            tmp_path / "fancy", run_json=fancy_json, **{k: _decorated(v) for k, v in kwargs.items()}
        )
    )
    assert_runs_identical(plain, fancy)


# ---------------------------------------------------------------------------------------------
# Round trips


def assert_bits_equal(a: np.ndarray, b: np.ndarray) -> None:
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape
    assert a.tobytes() == b.tobytes()  # bit for bit: -0.0 and 0.0 differ here


def assert_runs_identical(a: RunLog, b: RunLog) -> None:
    assert a.controls.kind == b.controls.kind
    assert_bits_equal(a.controls.t, b.controls.t)
    assert_bits_equal(a.controls.values, b.controls.values)
    for name in ("t", "tag_id", "range", "bearing"):
        assert_bits_equal(getattr(a.detections, name), getattr(b.detections, name))
    assert (a.groundtruth is None) == (b.groundtruth is None)
    if a.groundtruth is not None:
        assert_bits_equal(a.groundtruth.t, b.groundtruth.t)
        assert_bits_equal(a.groundtruth.pose, b.groundtruth.pose)
    ma, mb = a.meta, b.meta
    assert (ma.name, ma.source, ma.robot) == (mb.name, mb.source, mb.robot)
    assert (ma.control_rate_hz, ma.camera_rate_hz) == (mb.control_rate_hz, mb.camera_rate_hz)
    assert_bits_equal(ma.nominal_start, mb.nominal_start)
    assert_bits_equal(ma.camera_mounting, mb.camera_mounting)
    assert (ma.tag_map is None) == (mb.tag_map is None)
    if ma.tag_map is not None:
        assert sorted(ma.tag_map) == sorted(mb.tag_map)
        for tag in ma.tag_map:
            assert_bits_equal(ma.tag_map[tag], mb.tag_map[tag])
    assert ma.simulation == mb.simulation


def awkward_floats(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Random doubles with full 17-digit mantissas, plus values whose text is easy to get wrong.

    Within what a run may hold (below 30 in magnitude: speeds, ranges and positions near the
    map, headings within ±2π, `ekfslam.plausibility`); the doubles no run holds (1.8e308,
    2^53 + 2) round-trip in test_csv_text_round_trips_every_double.
    """
    x = rng.normal(size=shape) * 10.0 ** rng.integers(-8, 1, size=shape)
    flat = x.reshape(-1)
    specials = [-0.0, 0.1, 1e-300, 5e-324, 1 / 3, 6.283185307179586]
    flat[: len(specials)] = specials[: flat.size]
    return x


def test_csv_text_round_trips_every_double(tmp_path: Path) -> None:
    values = np.array([-0.0, 0.1, 1e-300, 5e-324, 1.7976931348623157e308, 1 / 3, 2.0**53 + 2])
    path = tmp_path / "rows.csv"
    path.write_text(csv_text(("t", "x"), [values, -values]))
    name, (t, x) = read_table(path, {"rows": ("t", "x")})
    assert name == "rows"
    assert t.tobytes() == values.tobytes() and x.tobytes() == (-values).tobytes()


def random_run(kind: str, *, with_truth: bool, with_map: bool, seed: int = 7) -> RunLog:
    rng = np.random.default_rng(seed)
    n, m, k = 200, 150, 60
    t = np.cumsum(rng.choice([0.0, 0.02, 0.0213], size=n)) + 1234567890.123  # repeated times too
    ids = rng.integers(0, 12, size=m)
    tag_map = {int(i): rng.uniform(-1, 1, size=2) for i in range(12)} if with_map else None
    meta = RunMeta(
        name="round-trip ✓",
        source="simulated",
        nominal_start=np.array([-0.375, -0.375, -0.0]),
        control_rate_hz=50.0,
        camera_rate_hz=None,
        robot=MecanumGeometry(0.0301, 0.0681, 0.0541) if kind == "wheels" else None,
        camera_mounting=np.array([0.05, -0.0, 1 / 3]),
        tag_map=tag_map,
        simulation={
            "seed": 7,
            "noise": {"range_sigma": 0.02, "bearing_sigma": 0.01},
            "true_start": [-0.37, -0.38, 0.01],
            "flags": [True, None, "x"],
        },
    )
    controls = Controls(
        t=t, kind=kind, values=awkward_floats(rng, (n, 4 if kind == "wheels" else 3))
    )
    # on the controls' clock; before the truth begins, so that random sightings are not held to
    # fit the random true poses (`ekfslam.plausibility.sightings_off_truth`)
    detections = Detections(
        t=np.sort(rng.uniform(t[0], t[0] + 0.4 * (t[-1] - t[0]), size=m)),
        tag_id=ids.astype(np.int64),
        range=np.abs(awkward_floats(rng, (m,))),
        bearing=np.concatenate([[-math.pi, math.pi, -0.0], rng.uniform(-math.pi, math.pi, m - 3)]),
    )
    truth = None
    if with_truth:
        start = t[0] + 0.45 * (t[-1] - t[0])
        truth = GroundTruth(t=np.linspace(start, t[-1], k), pose=awkward_floats(rng, (k, 3)))
    return RunLog(meta=meta, controls=controls, detections=detections, groundtruth=truth)


def folder_bytes(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.mark.parametrize(
    ("kind", "with_truth", "with_map"),
    [
        ("wheels", True, True),
        ("wheels", False, False),
        ("twist", True, False),
        ("twist", False, True),
    ],
)
def test_round_trip_is_bit_exact_and_byte_stable(
    tmp_path: Path, kind: str, with_truth: bool, with_map: bool
) -> None:
    run = random_run(kind, with_truth=with_truth, with_map=with_map)
    write_run(run, tmp_path / "a")
    back = read_run(tmp_path / "a")
    assert_runs_identical(run, back)
    write_run(back, tmp_path / "b")
    write_run(run, tmp_path / "c")
    first = folder_bytes(tmp_path / "a")
    expected = {"run.json", "controls.csv", "detections.csv"} | (
        {"groundtruth.csv"} if with_truth else set()
    )
    assert set(first) == expected
    assert folder_bytes(tmp_path / "b") == first
    assert folder_bytes(tmp_path / "c") == first


def test_written_files_follow_the_format(tmp_path: Path) -> None:
    meta = RunMeta(
        name="spec",
        source="recorded",
        nominal_start=np.array([0.0, -0.5, 0.25]),
        tag_map={10: np.array([0.75, 0.375]), 2: np.array([-0.75, 0.0])},
    )
    run = RunLog(
        meta=meta,
        controls=Controls(
            t=np.array([0.0, 0.1]),
            kind="twist",
            values=np.array([[0.1, -0.0, 1e-300], [0.2, 0.0, 0.5]]),
        ),
        detections=Detections(
            t=np.array([0.05]),
            tag_id=np.array([10]),
            range=np.array([1.5]),
            bearing=np.array([-0.25]),
        ),
    )
    folder = write_run(run, tmp_path / "run")
    assert (folder / "controls.csv").read_bytes() == (
        b"t,vx,vy,wz\n0.0,0.1,-0.0,1e-300\n0.1,0.2,0.0,0.5\n"
    )
    assert (
        folder / "detections.csv"
    ).read_bytes() == b"t,tag_id,range,bearing\n0.05,10,1.5,-0.25\n"
    text = (folder / "run.json").read_text(encoding="utf-8")
    assert text.startswith('{\n  "format": "ekfslam-run",\n  "format_version": 1,\n')
    assert "\r" not in text and text.endswith("}\n")
    doc = json.loads(text)
    assert doc["units"] == {"length": "m", "angle": "rad", "time": "s"}
    assert doc["tag_map"] == {"2": [-0.75, 0.0], "10": [0.75, 0.375]}
    assert list(doc["tag_map"]) == ["2", "10"]  # numeric order, not "10" < "2"
    assert doc["robot"] is None and doc["simulation"] is None
    assert doc["rates"] == {"controls_hz": None, "camera_hz": None}
    assert doc["camera_mounting"] == {"x": 0.0, "y": 0.0, "yaw": 0.0}
    assert doc["nominal_start"] == [0.0, -0.5, 0.25]
    assert not (folder / "groundtruth.csv").exists()


def test_empty_detections_round_trip(tmp_path: Path) -> None:
    run = read_run(make_run(tmp_path / "a", detections="t,tag_id,range,bearing\n"))
    write_run(run, tmp_path / "b")
    assert (tmp_path / "b" / "detections.csv").read_text() == "t,tag_id,range,bearing\n"
    assert_runs_identical(run, read_run(tmp_path / "b"))


# ---------------------------------------------------------------------------------------------
# Writing safely


def test_writer_refuses_a_non_empty_folder_and_overwrites_only_when_told(tmp_path: Path) -> None:
    with_truth = random_run("twist", with_truth=True, with_map=False)
    without = random_run("twist", with_truth=False, with_map=False, seed=8)
    folder = write_run(with_truth, tmp_path / "run")
    (folder / "notes.txt").write_text("mine")
    before = folder_bytes(folder)
    with pytest.raises(InputError, match="not empty") as info:
        write_run(without, folder)
    assert info.value.path == str(folder) and "overwrite=True" in str(info.value)
    assert folder_bytes(folder) == before
    write_run(without, folder, overwrite=True)
    assert not (folder / "groundtruth.csv").exists()  # stale truth would pair with the new run
    assert (folder / "notes.txt").read_text() == "mine"
    assert_runs_identical(without, read_run(folder))


def test_writer_accepts_an_existing_empty_folder_and_rejects_a_file(tmp_path: Path) -> None:
    run = random_run("twist", with_truth=False, with_map=False)
    (tmp_path / "empty").mkdir()
    write_run(run, tmp_path / "empty")
    assert (tmp_path / "empty" / "controls.csv").is_file()
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match="not a folder"):
        write_run(run, tmp_path / "file", overwrite=True)


def test_writer_validates_before_touching_the_disk(tmp_path: Path) -> None:
    run = random_run("twist", with_truth=False, with_map=False)
    t = run.controls.t.copy()
    t[5] = t[4] - 0.5
    bad = RunLog(run.meta, Controls(t=t, kind="twist", values=run.controls.values), run.detections)
    with pytest.raises(InputError) as info:
        write_run(bad, tmp_path / "out")
    assert (info.value.path, info.value.line) == ("controls.csv", 7)  # row 5 -> line 7
    assert "earlier than the previous row" in info.value.problem
    assert not (tmp_path / "out").exists()


def test_validate_run_checks_shapes_robot_and_tag_map() -> None:
    run = random_run("wheels", with_truth=True, with_map=True)
    validate_run(run)
    c = run.controls
    wrong_shape = RunLog(run.meta, Controls(c.t, "wheels", c.values[:, :3]), run.detections)
    with pytest.raises(InputError, match=r"shape \(200, 3\), expected \(200, 4\)"):
        validate_run(wrong_shape)
    meta = run.meta
    no_robot = RunMeta(meta.name, meta.source, meta.nominal_start, tag_map=meta.tag_map)
    with pytest.raises(InputError, match="robot"):
        validate_run(RunLog(no_robot, c, run.detections))
    small_map = {i: xy for i, xy in meta.tag_map.items() if i != 3}
    meta2 = RunMeta(meta.name, meta.source, meta.nominal_start, robot=meta.robot, tag_map=small_map)
    with pytest.raises(InputError) as info:
        validate_run(RunLog(meta2, c, run.detections), folder="out")
    first = int(np.flatnonzero(run.detections.tag_id == 3)[0])
    assert (info.value.path, info.value.line) == (str(Path("out", "detections.csv")), first + 2)
    assert "tag 3 is not in" in info.value.problem


# ---------------------------------------------------------------------------------------------
# Malformed CSV: every case names the file, the line and the problem

T = "t,vx,vy,wz\n"
D = "t,tag_id,range,bearing\n"
G = "t,x,y,theta\n"
CSV_CASES = [
    # (file, text, line, phrases)
    ("controls.csv", "t,w1,w2,w3\n0,1,1,1\n", 1, ["missing column w4", "expected header"]),
    (
        "controls.csv",
        "t,vx,vy,omega\n0,1,1,1\n",
        1,
        ["unknown column 'omega'", "missing column wz"],
    ),
    ("controls.csv", "t,vx,wz,vy\n0,1,1,1\n", 1, ["out of order", "'t,vx,vy,wz'"]),
    ("controls.csv", T + "0.0,0.1,0,0\n0.5,0.2,0.0\n", 3, ["expected 4 fields", "truncated"]),
    ("controls.csv", T + "0.0,0.1,0,0\n0.5,0.2,0,0,\n", 3, ["found 5"]),
    ("controls.csv", T + "0.0,0.1,0,0\n0.5,abc,0,0.1\n", 3, ["vx is not a number: 'abc'"]),
    ("controls.csv", T + "0.0,0.1,0,0\n0.5,0.1,,0.1\n", 3, ["vy is not a number: ''"]),
    ("controls.csv", T + "0.0,0.1,0,0\n0.5,0.1,0,1_0\n", 3, ["wz is not a number: '1_0'"]),
    ("controls.csv", T + "0.0,0.1,0,0\n0.5,0.1,nan,0\n", 3, ["vy is nan", "finite"]),
    ("controls.csv", T + "0.0,0.1,0,0\n0.5,0.1,0,inf\n", 3, ["wz is inf", "finite"]),
    ("controls.csv", T + "0.0,0.1,0,0\n-inf,0.1,0,0\n", 3, ["t is -inf", "finite"]),
    (
        "controls.csv",
        T + "12.3,0,0,0\n12.45,0,0,0\n12.40,0,0,0\n",
        4,
        ["time 12.4 s is earlier than the previous row (12.45 s)"],
    ),
    ("controls.csv", T + "0,0,0,0\n" + T + "1,0,0,0\n", 3, ["header line repeated"]),
    ("controls.csv", T + "0,0,0,0\nt,w1,w2,w3,w4\n1,0,0,0\n", 3, ["header line repeated"]),
    ("controls.csv", T + "0,0,0,0\n\n1,0,0,0\n", 3, ["blank line"]),
    ("controls.csv", "", 1, ["empty file", "'t,w1,w2,w3,w4' or 't,vx,vy,wz'"]),
    ("controls.csv", "\n  \n", 1, ["empty file"]),
    ("controls.csv", T, 2, ["no controls"]),
    ("controls.csv", T + "0;0;0;0\n", 2, ["expected 4 fields"]),
    # the earliest bad line wins, whatever kind of problem comes later
    ("controls.csv", T + "0,0,0,0\n1,x,0,0\n2,0,0\n", 3, ["vx is not a number"]),
    ("controls.csv", T + "0,0,0,0\n2,0,0,0\n1,0,0,0\n3,nan,0,0\n", 4, ["earlier"]),
    ("controls.csv", T + "0,0,0,0\n1,0,0,inf\n0,0,0,0\n", 3, ["wz is inf"]),
    ("detections.csv", "t,id,range,bearing\n", 1, ["unknown column 'id'", "missing column tag_id"]),
    ("detections.csv", "", 1, ["empty file", "'t,tag_id,range,bearing'"]),
    ("detections.csv", D + "0.1,1,1.2,0.3\n0.2,2,-1.5,0.3\n", 3, ["negative range -1.5 m"]),
    ("detections.csv", D + "0.1,1,1.2,30.0\n", 2, ["bearing 30.0 rad", "degrees by mistake?"]),
    ("detections.csv", D + "0.1,1,1.2,-3.2\n", 2, ["outside [-pi, pi]", "degrees by mistake?"]),
    ("detections.csv", D + "0.1,1,1.2,0.3\n0.2,3.5,1,0\n", 3, ["tag_id is not an integer: '3.5'"]),
    ("detections.csv", D + "0.1,A7,1.2,0.3\n", 2, ["tag_id is not an integer: 'A7'"]),
    ("detections.csv", D + "0.1,1,nan,0.3\n", 2, ["range is nan"]),
    ("detections.csv", D + "0.1,1,1,0\n0.1,99999999999999999999,1,0\n", 3, ["tag_id is not"]),
    ("detections.csv", D + "0.2,1,1,0\n0.1,1,1,0\n", 3, ["time 0.1 s is earlier", "(0.2 s)"]),
    ("detections.csv", D + "0.1,1,1,0\n0.1,2,1\n", 3, ["expected 4 fields"]),
    ("detections.csv", D + "0,1,1,0\n" + D, 3, ["header line repeated"]),
    (
        "groundtruth.csv",
        "t,x,y,yaw\n0,0,0,0\n",
        1,
        ["unknown column 'yaw'", "missing column theta"],
    ),
    ("groundtruth.csv", G, 2, ["no ground-truth rows"]),
    ("groundtruth.csv", G + "0,0,0,0\n1,0,inf,0\n", 3, ["y is inf"]),
    ("groundtruth.csv", G + "1,0,0,0\n0,0,0,0\n", 3, ["earlier than the previous row"]),
]


@pytest.mark.parametrize(("name", "text", "line", "phrases"), CSV_CASES)
def test_malformed_csv_is_reported_at_its_line(
    tmp_path: Path, name: str, text: str, line: int, phrases: list[str]
) -> None:
    folder = make_run(tmp_path, **{name.removesuffix(".csv"): text})
    err = error_of(folder)
    assert err.path == str(folder / name)
    assert err.line == line, str(err)
    for phrase in phrases:
        assert phrase in err.problem, str(err)
    assert str(err).startswith(f"{folder / name}:{line}: ")


def test_non_utf8_bytes_are_reported_at_their_line(tmp_path: Path) -> None:
    folder = make_run(tmp_path)
    (folder / "controls.csv").write_bytes(b"t,vx,vy,wz\n0,0,0,0\n1,0,0\xe9,0\n")
    err = error_of(folder)
    assert (err.path, err.line) == (str(folder / "controls.csv"), 3)
    assert "UTF-8" in err.problem


def test_wheel_controls_need_a_robot(tmp_path: Path) -> None:
    err = error_of(make_run(tmp_path, controls=WHEELS, robot=None))
    assert (err.path, err.line) == (str(tmp_path / "controls.csv"), 1)
    assert 'run.json has no "robot"' in err.problem


def test_detections_of_tags_missing_from_the_tag_map_are_errors(tmp_path: Path) -> None:
    folder = make_run(tmp_path, detections=D + "0.1,1,1,0\n0.2,7,1,0\n", tag_map={"1": [0, 0]})
    err = error_of(folder)
    assert (err.path, err.line) == (str(folder / "detections.csv"), 3)
    assert "tag 7 is not in run.json's tag_map" in err.problem and "known: 1" in err.problem


# ---------------------------------------------------------------------------------------------
# Missing files and malformed run.json


@pytest.mark.parametrize("missing", ["run.json", "controls.csv", "detections.csv"])
def test_missing_files_are_named(tmp_path: Path, missing: str) -> None:
    folder = make_run(tmp_path)
    (folder / missing).unlink()
    err = error_of(folder)
    assert (err.path, err.line) == (str(folder / missing), None)
    assert "missing file" in err.problem


def test_missing_folder_and_file_instead_of_folder(tmp_path: Path) -> None:
    err = error_of(tmp_path / "nowhere")
    assert err.path == str(tmp_path / "nowhere") and "run folder not found" in err.problem
    (tmp_path / "file").write_text("x")
    assert "is not a folder" in error_of(tmp_path / "file").problem


def json_error(tmp_path: Path, text: str) -> InputError:
    err = error_of(make_run(tmp_path, run_json=text))
    assert err.path == str(tmp_path / "run.json")
    return err


def test_invalid_json_reports_the_json_line(tmp_path: Path) -> None:
    good = json.dumps(run_doc(), indent=2)
    err = json_error(tmp_path, good.replace('"name": "demo",', '"name": "demo"'))
    assert err.line == line_with(good, '"source"') and "invalid JSON" in err.problem
    err = json_error(tmp_path, good.replace('"s"\n', '"s",\n'))  # trailing comma
    assert err.line == line_with(good, '"s"') + 1 and "invalid JSON" in err.problem


def doc_text(**changes: object) -> str:
    return json.dumps(run_doc(**changes), indent=2)


JSON_CASES = [
    # (changes to run.json, key whose line is reported (None: no line), phrases)
    ({"format": "rosbag"}, "format", ["not an ekfslam run", "'rosbag'", '"ekfslam-run"']),
    ({"format": _DROP}, None, ["not an ekfslam run", "None"]),
    (
        {"format_version": 2},
        "format_version",
        ["format_version 2 is not supported", "reads format_version 1"],
    ),
    ({"format_version": "1"}, "format_version", ["format_version '1' is not supported"]),
    ({"units": {"length": "mm", "angle": "rad", "time": "s"}}, "units", ["unknown units", '"mm"']),
    (
        {"units": {"length": "m", "angle": "deg", "time": "s"}},
        "units",
        ["unknown units", "degrees"],
    ),
    ({"units": _DROP}, None, ["missing key 'units'"]),
    ({"tagmap": {}}, "tagmap", ["unknown key 'tagmap'"]),
    ({"name": ""}, "name", ["non-empty string"]),
    ({"source": "sim"}, "source", ['"simulated" or "recorded"']),
    ({"nominal_start": [0, 0]}, "nominal_start", ["nominal_start", "3 finite numbers"]),
    ({"nominal_start": [0, "a", 0]}, "nominal_start", ["3 finite numbers", '"a"']),
    ({"nominal_start": [0, True, 0]}, "nominal_start", ["3 finite numbers"]),
    ({"nominal_start": _DROP}, None, ["missing key 'nominal_start'"]),
    ({"camera_mounting": {"x": 0, "y": 0}}, "camera_mounting", ["all of the keys x, y, yaw"]),
    ({"camera_mounting": {"x": 0, "y": "0", "yaw": 0}}, "camera_mounting", ["3 finite numbers"]),
    ({"tag_map": {"a": [0, 0]}}, "a", ["tag_map id 'a' is not an integer"]),
    ({"tag_map": {"1.5": [0, 0]}}, "1.5", ["tag_map id '1.5' is not an integer"]),
    ({"tag_map": {"1": [0, 0], "01": [1, 1]}}, "01", ["tag_map id 1 appears twice"]),
    ({"tag_map": {"1": [0]}}, "1", ["tag_map entry '1' must be 2 finite numbers"]),
    ({"tag_map": {"1": [0, "x"]}}, "1", ["2 finite numbers"]),
    ({"tag_map": [[0, 0]]}, "tag_map", ['"tag_map" must be an object']),
    ({"robot": {**ROBOT, "type": "diff"}}, "robot", ["'diff' is not supported"]),
    ({"robot": {"type": "mecanum", "lx": 0.1, "ly": 0.1}}, "robot", ["all of the keys"]),
    ({"robot": {**ROBOT, "lx": -0.1}}, "lx", ["robot lx must be a positive number"]),
    (
        {"rates": {"controls_hz": 0}},
        "controls_hz",
        ["controls_hz must be a positive number or null"],
    ),
    ({"rates": {"imu_hz": 100}}, "rates", ["keys controls_hz, camera_hz"]),
    ({"simulation": [1, 2]}, "simulation", ['"simulation" must be an object']),
]


@pytest.mark.parametrize(("changes", "key", "phrases"), JSON_CASES)
def test_malformed_run_json(
    tmp_path: Path, changes: dict, key: str | None, phrases: list[str]
) -> None:
    text = doc_text(**changes)
    err = json_error(tmp_path, text)
    assert err.line == (line_with(text, f'"{key}"') if key else None), str(err)
    for phrase in phrases:
        assert phrase in err.problem, str(err)


def test_run_json_nan_duplicates_and_non_objects(tmp_path: Path) -> None:
    text = doc_text().replace("-0.375,\n    0.0\n", "-0.375,\n    NaN\n")
    err = json_error(tmp_path, text)
    assert err.line == line_with(text, "NaN") and "NaN is not allowed" in err.problem
    text = doc_text(nominal_start=[0, 1.5, 0]).replace("1.5", "1e400")  # parses as inf
    err = json_error(tmp_path, text)
    assert err.line == line_with(text, "nominal_start") and "3 finite numbers" in err.problem
    text = doc_text().replace('"name": "demo",', '"name": "demo",\n  "name": "again",')
    err = json_error(tmp_path, text)
    assert err.line == line_with(text, '"name"', nth=1) and "'name' appears twice" in err.problem
    err = json_error(tmp_path, "[1, 2]\n")
    assert err.line is None and "not an ekfslam run" in err.problem


def test_the_examples_in_data_readme_are_a_valid_run(tmp_path: Path) -> None:
    readme = (Path(__file__).resolve().parents[2] / "data" / "README.md").read_text("utf-8")
    blocks = re.findall(r"<!-- example: (\S+) -->\n```\w*\n(.*?)```", readme, flags=re.DOTALL)
    assert sorted(name for name, _ in blocks) == sorted(
        ["run.json", "controls.csv", "detections.csv", "groundtruth.csv"]
    )
    for name, text in blocks:
        (tmp_path / name).write_text(text, encoding="utf-8")
    run = read_run(tmp_path)
    assert run.controls.kind == "wheels" and len(run.controls.t) == 4
    assert len(run.meta.tag_map) == 8 and run.detections.tag_id.tolist() == [0, 1, 0, 1]
    # the example detections are consistent with the example ground truth and tag map
    for t, tag, rng, bearing in zip(
        *(getattr(run.detections, n) for n in ("t", "tag_id", "range", "bearing")), strict=True
    ):
        x, y, theta = run.groundtruth.pose[np.flatnonzero(run.groundtruth.t == t)[0]]
        dx, dy = run.meta.tag_map[int(tag)] - (x, y)
        assert math.hypot(dx, dy) == pytest.approx(rng, abs=1e-4)
        assert math.atan2(dy, dx) - theta == pytest.approx(bearing, abs=1e-4)
    # and the file written back is byte for byte the example
    write_run(run, tmp_path / "again")
    for name, text in blocks:
        assert (tmp_path / "again" / name).read_text("utf-8") == text


# ---------------------------------------------------------------------------------------------
# run.json that used to end in a traceback, and files on different clocks


def test_run_json_numbers_that_break_python_are_one_error_at_their_line(tmp_path: Path) -> None:
    good = doc_text(tag_map={"1": [0.5, 0.5]})
    x_start, y_start = "-0.375,\n    -0.375", ",\n    -0.375"
    cases = {
        "id beyond int64": (good.replace('"1": [', '"99999999999999999999": ['), "64 bits"),
        "integer too large for a float": (
            good.replace("-0.375,\n    -0.375", "1" + "0" * 400 + ",\n    -0.375"),
            "finite numbers",
        ),
        "5,000-digit integer": (good.replace(x_start, "9" * 5000 + y_start), "digits"),
        "nominal_start 1e308": (good.replace(x_start, "1e308" + y_start), "plausible"),
        "heading in degrees": (good.replace("-0.375,\n    0.0", "-0.375,\n    90.0"), "degrees"),
    }
    for name, (text, word) in cases.items():
        assert text != good, name
        err = json_error(tmp_path / name.replace(" ", "-"), text)
        assert err.line is not None, name
        assert word in err.problem, (name, err.problem)
        assert len(str(err)) < 300, name  # a 5,000-digit number is not echoed whole


def test_deeply_nested_run_json_is_one_error(tmp_path: Path) -> None:
    text = doc_text().replace('"simulation": null', '"simulation": ' + "[" * 100_000)
    err = json_error(tmp_path, text)
    assert "nested too deeply" in err.problem and err.line == line_with(text, '"simulation"')


def test_a_folder_or_a_symlink_loop_named_run_json_is_not_called_missing(tmp_path: Path) -> None:
    folder = make_run(tmp_path / "dir")
    (folder / "run.json").unlink()
    (folder / "run.json").mkdir()
    assert "is a folder, not a file" in error_of(folder).problem
    loop = make_run(tmp_path / "loop")
    (loop / "run.json").unlink()
    (loop / "run.json").symlink_to(loop / "run.json")
    err = error_of(loop)
    assert err.path == str(loop / "run.json") and "symbolic link" in err.problem


def test_validate_run_refuses_an_implausible_start_pose() -> None:
    run = random_run("twist", with_truth=False, with_map=False)
    meta = RunMeta(name="x", source="recorded", nominal_start=np.array([1e308, 0.0, 0.0]))
    with pytest.raises(InputError, match="plausible"):
        validate_run(RunLog(meta, run.controls, run.detections))


@pytest.mark.parametrize(
    ("detections", "groundtruth", "bad", "line"),
    [
        # detections in ns beside controls in s (0 to 1 s)
        ("t,tag_id,range,bearing\n100000000,1,1.2,0.3\n", None, "detections.csv", 2),
        ("t,tag_id,range,bearing\n0.1,1,1.2,0.3\n3.5,1,1.2,0.3\n", None, "detections.csv", 3),
        # ground truth on another clock: ATE used to be NaN
        (DETECTIONS, "t,x,y,theta\n1e9,0,0,0\n1.000000001e9,0,0,0\n", "groundtruth.csv", 2),
        # inside the margin, but covering a sliver of the run
        (DETECTIONS, "t,x,y,theta\n0.0,0,0,0\n0.2,0,0,0\n", "groundtruth.csv", None),
    ],
)
def test_files_on_another_clock_are_refused_naming_both_files(
    tmp_path: Path, detections: str, groundtruth: str | None, bad: str, line: int | None
) -> None:
    err = error_of(make_run(tmp_path, detections=detections, groundtruth=groundtruth))
    assert (err.path, err.line) == (str(tmp_path / bad), line)
    assert "controls.csv" in err.problem and "0.000 to 1.000 s" in err.problem
    assert "different clocks" in err.problem


def test_a_sensor_that_starts_a_little_early_is_accepted(tmp_path: Path) -> None:
    # MRCLAM's Vicon starts 6-9 s before the odometry of a 900 s run; here 0.5 s before 1 s
    truth = "t,x,y,theta\n-0.5,0,0,0\n1.2,0,0,0\n"
    run = read_run(make_run(tmp_path, groundtruth=truth))
    assert run.groundtruth is not None and len(run.groundtruth.t) == 2
