"""Generated bad input for every reader: run folders (CSVs and run.json), MRCLAM .dat files, ROS 2
bags and runs of camera frames (issue 27).

Each test starts from a clean input, changes it the way a third party might (arbitrary bytes,
a truncation, nasty bytes anywhere, a cell replaced by anything, a column scaled by anything, a
run.json value swapped for any JSON) and asserts the one property: the reader ends in one of our
errors, one line naming the input, within `generated.CASE_SECONDS`; or what it returns keeps
every rule the reader enforces (and replays). Changes that mean nothing (a BOM, CRLF, spaces, a
blank tail, key order) give the clean input's run exactly. The number of cases per test is the
hypothesis profile's (`generated.CI_EXAMPLES` in CI); tests/conftest.py prints how many each
reader saw.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from generated import NASTY_BYTES, cells, numbers_of_every_kind, seen, verdict
from hypothesis import given, settings
from hypothesis import strategies as st

from ekfslam.core.kinematics import wheels_to_twist
from ekfslam.logs.edit import truncate
from ekfslam.logs.mrclam.load import load_mrclam
from ekfslam.logs.runlog import RunLog, read_run, validate_run, write_run
from ekfslam.pipeline import replay
from ekfslam.sim.simulation import SimulationConfig, simulate

FILES = ("run.json", "controls.csv", "detections.csv", "groundtruth.csv")
CSV_FILES = FILES[1:]


# ------------------------------------------------------------------------------ clean inputs
@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, RunLog]:
    """A short simulated run (12 s of the square) as a run folder, and the run it reads back as."""
    run = truncate(simulate(SimulationConfig(trajectory="square", laps=1, seed=3)), 12.0)
    folder = write_run(run, tmp_path_factory.mktemp("clean") / "run")
    return folder, read_run(folder)


def copied(source: Path) -> tuple[tempfile.TemporaryDirectory, Path]:
    """A fresh copy of `source` for one example (hypothesis reuses function-scoped fixtures)."""
    box = tempfile.TemporaryDirectory(prefix="ekfslam-generated-")
    dest = Path(box.name) / source.name
    shutil.copytree(source, dest, symlinks=True)
    return box, dest


def assert_same_run(a: RunLog, b: RunLog) -> None:
    np.testing.assert_array_equal(a.controls.t, b.controls.t)
    np.testing.assert_array_equal(a.controls.values, b.controls.values)
    for name in ("t", "tag_id", "range", "bearing"):
        np.testing.assert_array_equal(getattr(a.detections, name), getattr(b.detections, name))
    assert (a.groundtruth is None) == (b.groundtruth is None)
    if a.groundtruth is not None:
        np.testing.assert_array_equal(a.groundtruth.pose, b.groundtruth.pose)
    np.testing.assert_array_equal(a.meta.nominal_start, b.meta.nominal_start)
    assert sorted(a.meta.tag_map or {}) == sorted(b.meta.tag_map or {})


def check_run_folder(folder: Path, target: str = "read_run") -> tuple[str, object]:
    """read_run on a changed folder: our error naming a file in it, or a run that keeps every
    rule (`validate_run`) and replays (a replay error is ours too)."""
    seen(target)
    kind, value = verdict(lambda: read_run(folder), (str(folder),))
    if kind == "ok":
        validate_run(value)
        kind2, _ = verdict(lambda: replay(value), (value.meta.name, "replay"))
        assert kind2 == "ok", "a run the reader accepted did not replay"
    return kind, value


# ------------------------------------------------------------------------------ changes
def replace_bytes(data: bytes) -> Callable[[bytes], bytes]:
    return lambda _: data


positions = st.floats(0.0, 1.0)
insertions = st.lists(st.tuples(positions, st.sampled_from(NASTY_BYTES)), min_size=1, max_size=4)


def insert_at(old: bytes, where: list[tuple[float, bytes]]) -> bytes:
    for fraction, token in sorted(where, reverse=True):
        i = int(fraction * len(old))
        old = old[:i] + token + old[i:]
    return old


def replace_cell(text: str, separator: str, row: float, column: int, cell: str) -> str:
    """`text` with the cell at (a data row chosen by `row` in [0, 1], `column`) set to `cell`."""
    lines = text.split("\n")
    data = [i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")][1:]
    if separator == " ":  # MRCLAM: every non-# line holds data
        data = [i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#")]
    if not data:
        return text
    i = data[min(int(row * len(data)), len(data) - 1)]
    parts = lines[i].rstrip("\r").split(separator if separator != " " else None)
    parts[column % len(parts)] = cell
    lines[i] = separator.join(parts) + ("\r" if lines[i].endswith("\r") else "")
    return "\n".join(lines)


def scale_column(text: str, separator: str, column: int, factor: float) -> str:
    """Every data cell of `column` multiplied by `factor` (printed with repr)."""
    out = []
    header_left = separator == ","
    for line in text.split("\n"):
        body = line.rstrip("\r")
        if not body.strip() or body.startswith("#") or header_left:
            header_left = header_left and not body.strip()
            out.append(line)
            continue
        parts = body.split(separator if separator != " " else None)
        j = column % len(parts)
        try:
            parts[j] = repr(float(parts[j]) * factor)
        except ValueError:
            pass
        out.append(separator.join(parts) + ("\r" if line.endswith("\r") else ""))
    return "\n".join(out)


# ------------------------------------------------------------------------------ run folders
@pytest.mark.parametrize("name", FILES)
@given(data=st.binary(max_size=2000))
def test_a_run_file_of_arbitrary_bytes(clean, name: str, data: bytes) -> None:
    box, folder = copied(clean[0])
    with box:
        (folder / name).write_bytes(data)
        check_run_folder(folder)


@pytest.mark.parametrize("name", FILES)
@given(cut=positions)
def test_a_truncated_run_file(clean, name: str, cut: float) -> None:
    box, folder = copied(clean[0])
    with box:
        path = folder / name
        data = path.read_bytes()
        path.write_bytes(data[: int(cut * len(data))])
        check_run_folder(folder)


@pytest.mark.parametrize("name", FILES)
@given(where=insertions)
def test_nasty_bytes_anywhere_in_a_run_file(clean, name: str, where) -> None:
    box, folder = copied(clean[0])
    with box:
        path = folder / name
        path.write_bytes(insert_at(path.read_bytes(), where))
        check_run_folder(folder)


@pytest.mark.parametrize("name", CSV_FILES)
@given(row=positions, column=st.integers(0, 4), cell=cells)
def test_a_csv_cell_replaced_by_anything(clean, name: str, row: float, column: int, cell: str):
    box, folder = copied(clean[0])
    with box:
        path = folder / name
        path.write_text(replace_cell(path.read_text(), ",", row, column, cell))
        check_run_folder(folder)


@pytest.mark.parametrize("name", CSV_FILES)
@given(column=st.integers(0, 4), factor=numbers_of_every_kind())
def test_a_csv_column_scaled_by_anything(clean, name: str, column: int, factor: float) -> None:
    box, folder = copied(clean[0])
    with box:
        path = folder / name
        path.write_text(scale_column(path.read_text(), ",", column, factor))
        check_run_folder(folder)


NEUTRAL = {
    "bom": lambda b: b"\xef\xbb\xbf" + b,
    "crlf": lambda b: b.replace(b"\n", b"\r\n"),
    "blank tail": lambda b: b + b"\n\n  \n",
    "spaces": lambda b: b.replace(b",", b" , "),
}


@pytest.mark.parametrize("name", FILES)
@given(changes=st.sets(st.sampled_from(sorted(NEUTRAL)), min_size=1))
def test_changes_that_mean_nothing_give_the_same_run(clean, name: str, changes: set[str]):
    box, folder = copied(clean[0])
    with box:
        path = folder / name
        data = path.read_bytes()
        for change in sorted(changes):
            if name == "run.json" and change == "spaces":
                continue  # a comma inside a JSON string is not a separator
            data = NEUTRAL[change](data)
        path.write_bytes(data)
        kind, run = check_run_folder(folder)
        assert kind == "ok", f"{sorted(changes)} refused: {run}"
        assert_same_run(run, clean[1])


json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=10),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner, max_size=4)
    ),
    max_leaves=8,
)


def _paths(doc, prefix=()):
    """Every key path of a JSON document (dicts only)."""
    if isinstance(doc, dict):
        for key, value in doc.items():
            yield (*prefix, key)
            yield from _paths(value, (*prefix, key))


@given(pick=positions, value=json_values, action=st.sampled_from(["replace", "delete", "add"]))
def test_a_run_json_value_replaced_by_any_json(clean, pick: float, value, action: str) -> None:
    box, folder = copied(clean[0])
    with box:
        path = folder / "run.json"
        doc = json.loads(path.read_text())
        paths = list(_paths(doc))
        key_path = paths[min(int(pick * len(paths)), len(paths) - 1)]
        parent = doc
        for key in key_path[:-1]:
            parent = parent[key]
        if action == "replace":
            parent[key_path[-1]] = value
        elif action == "delete":
            del parent[key_path[-1]]
        else:
            parent[f"x{len(paths)}"] = value
        path.write_text(json.dumps(doc, indent=1, allow_nan=True))
        check_run_folder(folder)


@given(order=st.randoms(use_true_random=False), indent=st.sampled_from([None, 0, 1, 4, "\t"]))
def test_run_json_key_order_and_layout_mean_nothing(clean, order, indent) -> None:
    box, folder = copied(clean[0])
    with box:
        path = folder / "run.json"
        doc = json.loads(path.read_text())
        keys = list(doc)
        order.shuffle(keys)
        path.write_text(json.dumps({k: doc[k] for k in keys}, indent=indent))
        kind, run = check_run_folder(folder)
        assert kind == "ok", run
        assert_same_run(run, clean[1])


# ------------------------------------------------------------------------------ MRCLAM
MRCLAM_FILES = (
    "Barcodes.dat",
    "Landmark_Groundtruth.dat",
    "Robot1_Odometry.dat",
    "Robot1_Measurement.dat",
    "Robot1_Groundtruth.dat",
)
CLOCK = 1248446180.0  # MRCLAM's clock is Unix time


def write_mrclam(run: RunLog, folder: Path) -> Path:
    """`run` as a MRCLAM dataset folder (robot 1; tag i is subject 6 + i, barcode 100 + i),
    written as MRCLAM writes its files: whitespace, # headers, CRLF."""
    folder.mkdir(parents=True)

    def dat(name: str, header: str, rows) -> None:
        lines = [f"# {header}", "#"] + ["   ".join(repr(float(v)) for v in row) for row in rows]
        (folder / name).write_bytes(("\r\n".join(lines) + "\r\n").encode())

    tags = sorted(run.meta.tag_map)
    barcodes = [(s, b) for s, b in zip((1, 2, 3, 4, 5), (5, 14, 41, 32, 23), strict=True)]
    barcodes += [(6 + k, 100 + k) for k in range(len(tags))]
    dat("Barcodes.dat", "Subject #    Barcode #", barcodes)
    landmarks = [(6 + k, *run.meta.tag_map[tag], 0.001, 0.001) for k, tag in enumerate(tags)]
    dat(
        "Landmark_Groundtruth.dat",
        "Subject #    x [m]    y [m]    x std-dev [m]    y std-dev [m]",
        landmarks,
    )
    twist = wheels_to_twist(run.controls.values, run.meta.robot)
    dat(
        "Robot1_Odometry.dat",
        "Time [s]    Forward velocity [m/s]    Angular velocity[rad/s]",
        zip(run.controls.t + CLOCK, twist[:, 0], twist[:, 2], strict=True),
    )
    d = run.detections
    subject = {tag: 100 + k for k, tag in enumerate(tags)}
    dat(
        "Robot1_Measurement.dat",
        "Time [s]    Subject #    range [m]    bearing [rad]",
        zip(d.t + CLOCK, [subject[int(i)] for i in d.tag_id], d.range, d.bearing, strict=True),
    )
    g = run.groundtruth
    dat(
        "Robot1_Groundtruth.dat",
        "Time [s]    x [m]    y [m]    orientation [rad]",
        zip(g.t + CLOCK, *g.pose.T, strict=True),
    )
    return folder


@pytest.fixture(scope="module")
def clean_mrclam(clean, tmp_path_factory: pytest.TempPathFactory):
    folder = write_mrclam(clean[1], tmp_path_factory.mktemp("mrclam") / "MRCLAM_Dataset9")
    return folder, load_mrclam(folder, 1)[0]


def check_mrclam(folder: Path) -> tuple[str, object]:
    seen("load_mrclam")
    kind, value = verdict(lambda: load_mrclam(folder, 1), (str(folder),))
    if kind == "ok":
        run = value[0]
        # our format's rules; MRCLAM's Vicon truth need not cover the run (only be on its clock)
        validate_run(dataclasses.replace(run, groundtruth=None))
        assert run.groundtruth is None or np.isfinite(run.groundtruth.pose).all()
        kind2, _ = verdict(lambda: replay(run), (run.meta.name, "replay"))
        assert kind2 == "ok", "a run the loader accepted did not replay"
        return kind, run
    return kind, value


@pytest.mark.parametrize("name", MRCLAM_FILES)
@given(data=st.binary(max_size=2000))
def test_a_mrclam_file_of_arbitrary_bytes(clean_mrclam, name: str, data: bytes) -> None:
    box, folder = copied(clean_mrclam[0])
    with box:
        (folder / name).write_bytes(data)
        check_mrclam(folder)


@pytest.mark.parametrize("name", MRCLAM_FILES)
@given(cut=positions, where=insertions)
def test_a_mrclam_file_truncated_with_nasty_bytes(clean_mrclam, name: str, cut: float, where):
    box, folder = copied(clean_mrclam[0])
    with box:
        path = folder / name
        data = path.read_bytes()
        path.write_bytes(insert_at(data[: max(int(cut * len(data)), len(data) // 2)], where))
        check_mrclam(folder)


@pytest.mark.parametrize("name", MRCLAM_FILES)
@given(row=positions, column=st.integers(0, 4), cell=cells)
def test_a_mrclam_cell_replaced_by_anything(clean_mrclam, name: str, row, column, cell) -> None:
    box, folder = copied(clean_mrclam[0])
    with box:
        path = folder / name
        text = path.read_bytes().decode()
        path.write_bytes(replace_cell(text, " ", row, column, cell).encode("utf-8", "replace"))
        check_mrclam(folder)


@pytest.mark.parametrize("name", MRCLAM_FILES[2:])
@given(column=st.integers(0, 3), factor=numbers_of_every_kind())
def test_a_mrclam_column_scaled_by_anything(clean_mrclam, name: str, column, factor) -> None:
    box, folder = copied(clean_mrclam[0])
    with box:
        path = folder / name
        path.write_bytes(scale_column(path.read_bytes().decode(), " ", column, factor).encode())
        check_mrclam(folder)


@pytest.mark.parametrize("name", MRCLAM_FILES)
@given(changes=st.sets(st.sampled_from(["bom", "lf", "tabs", "blank tail"]), min_size=1))
def test_mrclam_changes_that_mean_nothing_give_the_same_run(clean_mrclam, name, changes) -> None:
    box, folder = copied(clean_mrclam[0])
    with box:
        path = folder / name
        data = path.read_bytes()
        edits = {
            "bom": lambda b: b"\xef\xbb\xbf" + b,
            "lf": lambda b: b.replace(b"\r\n", b"\n"),
            "tabs": lambda b: b.replace(b"   ", b"\t"),
            "blank tail": lambda b: b + b"\r\n\r\n",
        }
        for change in sorted(changes):
            data = edits[change](data)
        path.write_bytes(data)
        kind, run = check_mrclam(folder)
        assert kind == "ok", f"{sorted(changes)} refused: {run}"
        assert_same_run(run, clean_mrclam[1])


# ------------------------------------------------------------------------------ ROS bags
@pytest.fixture(scope="module")
def clean_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from adversarial_corpus import rosbag_folder  # the corpus's bag: /odom and /tf

    return rosbag_folder(tmp_path_factory.mktemp("bag"))


def check_bag(bag: Path) -> None:
    from ekfslam.logs.rosbag import read_rosbag
    from ekfslam.logs.rosbag_spec import RosbagSpec

    seen("read_rosbag")
    spec = RosbagSpec(twist_topic="/odom", detections_topic="/tf")
    kind, value = verdict(lambda: read_rosbag(bag, spec), (str(bag),))
    if kind == "ok":
        run = value[0]
        assert np.isfinite(run.controls.values).all() and np.isfinite(run.detections.range).all()


def _bag_files(bag: Path) -> list[Path]:
    return sorted(p for p in bag.iterdir() if p.is_file())


@pytest.mark.slow
@given(which=st.integers(0, 9), cut=positions, where=insertions, whole=st.booleans())
def test_a_ros_bag_truncated_or_with_nasty_bytes(clean_bag, which, cut, where, whole) -> None:
    box, bag = copied(clean_bag)
    with box:
        files = _bag_files(bag)
        path = files[which % len(files)]
        data = path.read_bytes()
        data = data[: int(cut * len(data))] if whole else insert_at(data, where)
        path.write_bytes(data)
        check_bag(bag)


@pytest.mark.slow
@given(which=st.integers(0, 9), data=st.binary(max_size=1500))
def test_a_ros_bag_file_of_arbitrary_bytes(clean_bag, which: int, data: bytes) -> None:
    box, bag = copied(clean_bag)
    with box:
        files = _bag_files(bag)
        files[which % len(files)].write_bytes(data)
        check_bag(bag)


# ------------------------------------------------------------------------------ frames runs
@pytest.fixture(scope="module")
def clean_frames(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, RunLog]:
    """A run of camera frames: 2 s of the square rendered at 10 Hz (21 frames, mp4v video)."""
    from ekfslam.vision.frames_run import read_frames_run, with_camera, write_frames_run

    run = truncate(simulate(SimulationConfig(trajectory="square", laps=1, seed=3)), 2.0)
    folder = tmp_path_factory.mktemp("frames") / "frames-run"
    write_frames_run(with_camera(run), folder)
    return folder, read_frames_run(folder)[0]


def check_frames(folder: Path) -> None:
    from ekfslam.vision.frames_run import read_frames_run

    seen("read_frames_run")
    kind, value = verdict(lambda: read_frames_run(folder), (str(folder),))
    if kind == "ok":
        validate_run(value[0])


@pytest.mark.slow
@settings(max_examples=30)  # each case detects the tags in 21 frames
@given(row=positions, column=st.integers(0, 1), cell=cells)
def test_a_frames_csv_cell_replaced_by_anything(clean_frames, row, column, cell) -> None:
    box, folder = copied(clean_frames[0])
    with box:
        path = folder / "frames.csv"
        path.write_text(replace_cell(path.read_text(), ",", row, column, cell))
        check_frames(folder)


@pytest.mark.slow
@settings(max_examples=30)
@given(name=st.sampled_from(["frames.csv", "frames.mp4"]), cut=positions, where=insertions)
def test_a_frames_file_truncated_or_with_nasty_bytes(clean_frames, name, cut, where) -> None:
    box, folder = copied(clean_frames[0])
    with box:
        path = folder / name
        data = path.read_bytes()
        cut_at = int(cut * len(data))
        path.write_bytes(insert_at(data[:cut_at], where) if cut < 0.5 else insert_at(data, where))
        check_frames(folder)


@pytest.mark.slow
@settings(max_examples=30)
@given(
    kind=st.sampled_from(["video", "images", "VIDEO", "", 3]),
    file=cells
    | st.sampled_from(["frames.mp4", "../x.mp4", "/etc/passwd", "frames/%06d.png", "%d%d.png"]),
)
def test_a_frames_spec_replaced_by_anything(clean_frames, kind, file) -> None:
    box, folder = copied(clean_frames[0])
    with box:
        path = folder / "run.json"
        doc = json.loads(path.read_text())
        doc["frames"] = {"kind": kind, "file": file}
        path.write_text(json.dumps(doc, indent=1))
        check_frames(folder)
