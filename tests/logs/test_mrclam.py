"""The MRCLAM loader: every robot of Dataset 7, and malformed copies made in tmp_path.

The expected numbers are computed here from the raw files with plain Python (line counting,
string splitting), independently of the loader's numpy parsing.
"""

from __future__ import annotations

import bisect
import functools
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ekfslam.errors import InputError
from ekfslam.logs.mrclam.load import interpolate_pose, load_mrclam

pytestmark = pytest.mark.shared_data

ROBOTS = [1, 2, 3, 4, 5]
HEADER_LINES = 4  # every MRCLAM file starts with four '#' lines


@functools.cache
def data_lines(path: Path) -> tuple[str, ...]:
    """Every non-header, non-blank line, read as plain text (cached: the files are read-only)."""
    with open(path, newline="") as f:
        lines = f.read().splitlines()
    return tuple(line for line in lines if line.strip() and not line.startswith("#"))


def data_rows(path: Path) -> list[list[str]]:
    return [line.split() for line in data_lines(path)]


def column(path: Path, index: int) -> list[float]:
    return [float(line.split()[index]) for line in data_lines(path)]


def barcode_table(folder: Path) -> dict[int, int]:
    return {int(b): int(s) for s, b in data_rows(folder / "Barcodes.dat")}


@pytest.fixture(scope="module")
def loaded(mrclam7: Path) -> dict:
    return {robot: load_mrclam(mrclam7, robot) for robot in ROBOTS}


@pytest.mark.parametrize("robot", ROBOTS)
def test_row_counts_add_up_to_the_file(mrclam7: Path, loaded: dict, robot: int) -> None:
    run, report = loaded[robot]
    odometry = data_lines(mrclam7 / f"Robot{robot}_Odometry.dat")
    measurements = data_rows(mrclam7 / f"Robot{robot}_Measurement.dat")
    truth = data_lines(mrclam7 / f"Robot{robot}_Groundtruth.dat")

    assert report.odometry_rows == len(odometry) == len(run.controls.t) > 50_000
    assert report.groundtruth_rows == len(truth) == len(run.groundtruth.t) > 50_000
    assert report.measurement_rows == len(measurements)
    dropped = report.robot_sightings_dropped + report.unknown_barcodes_dropped
    assert report.measurements_kept + dropped == len(measurements)
    assert len(run.detections.t) == report.measurements_kept

    # the drop counts, recomputed from the text
    subjects = barcode_table(mrclam7)
    barcodes = [int(row[1]) for row in measurements]
    robot_sightings = sum(1 for b in barcodes if subjects.get(b) in {1, 2, 3, 4, 5})
    unknown = {b for b in barcodes if b not in subjects}
    assert report.robot_sightings_dropped == robot_sightings > 0
    assert report.unknown_barcodes == frozenset(unknown)
    assert report.unknown_barcodes_dropped == sum(1 for b in barcodes if b in unknown)

    times = column(mrclam7 / f"Robot{robot}_Odometry.dat", 0)
    assert report.odometry_duplicate_times == sum(a == b for a, b in itertools.pairwise(times))
    assert report.odometry_max_gap_s == pytest.approx(max(np.diff(times)))
    assert report.groundtruth_first_time == float(truth[0].split()[0])
    assert report.groundtruth_last_time == float(truth[-1].split()[0])


def test_robot_3_sees_two_unknown_barcodes(loaded: dict) -> None:
    _, report = loaded[3]
    assert report.unknown_barcodes == {34, 52}
    assert report.unknown_barcodes_dropped == 9
    assert "9 sightings of unknown barcodes 34, 52 (not in Barcodes.dat)" in report.summary()
    as_json = json.loads(json.dumps(report.as_dict()))
    assert as_json["dropped"]["unknown_barcodes"]["barcodes"] == [34, 52]
    assert as_json["dropped"]["unknown_barcodes"]["count"] == 9
    assert as_json["dropped"]["robot_sightings"]["count"] == report.robot_sightings_dropped
    assert "9 sightings of unknown barcodes 34, 52 (not in Barcodes.dat)" in report.lines()[1]


def test_the_load_report_separates_what_was_loaded_from_what_was_dropped(loaded: dict) -> None:
    """Regression: "dropped while loading: odometry_rows 61785, ..., 1.0049998760223389"."""
    _, report = loaded[3]
    d = report.as_dict()
    assert set(d) == {"dataset", "robot", "loaded", "dropped"}
    assert set(d["dropped"]) == {"robot_sightings", "unknown_barcodes", "beyond_range"}
    assert all("reason" in v and "count" in v for v in d["dropped"].values())
    assert d["loaded"]["odometry_rows"] == report.odometry_rows  # loaded, not dropped
    gap = d["loaded"]["odometry_max_gap_s"]
    assert gap == round(report.odometry_max_gap_s, 3) and len(repr(gap)) <= 6
    loaded_line, dropped_line = report.lines()
    assert loaded_line.startswith(f"loaded: {report.odometry_rows} odometry rows (largest gap ")
    assert f"gap {report.odometry_max_gap_s:.3f} s," in loaded_line
    assert dropped_line.startswith(f"dropped: {report.robot_sightings_dropped} robot sightings ")
    assert "odometry" not in dropped_line and "True" not in loaded_line + dropped_line


@pytest.mark.parametrize("robot", ROBOTS)
def test_detections_are_landmarks_with_wrapped_bearings(
    mrclam7: Path, loaded: dict, robot: int
) -> None:
    run, _ = loaded[robot]
    det = run.detections
    assert det.tag_id.dtype == np.int64
    assert set(det.tag_id.tolist()) <= set(range(6, 21))
    assert len(set(det.tag_id.tolist())) >= 10
    assert np.all((det.bearing >= -math.pi) & (det.bearing < math.pi))
    assert np.all(det.range >= 0)

    # the first kept sighting, found by hand in the text
    subjects = barcode_table(mrclam7)
    rows = data_rows(mrclam7 / f"Robot{robot}_Measurement.dat")
    first = next(r for r in rows if subjects.get(int(r[1]), 0) > 5)
    assert det.t[0] == float(first[0])
    assert det.tag_id[0] == subjects[int(first[1])]
    assert det.range[0] == float(first[2])
    assert det.bearing[0] == float(first[3])


@pytest.mark.parametrize("robot", ROBOTS)
def test_controls_are_unicycle_twists(mrclam7: Path, loaded: dict, robot: int) -> None:
    run, _ = loaded[robot]
    controls = run.controls
    assert controls.kind == "twist"
    assert controls.values.shape == (len(controls.t), 3)
    assert np.all(controls.values[:, 1] == 0.0)
    rows = data_lines(mrclam7 / f"Robot{robot}_Odometry.dat")
    for i in (0, len(rows) // 2, -1):
        t, v, w = (float(x) for x in rows[i].split())
        assert (controls.t[i], controls.values[i, 0], controls.values[i, 2]) == (t, v, w)


@pytest.mark.parametrize("robot", ROBOTS)
def test_times_are_non_decreasing(loaded: dict, robot: int) -> None:
    run, report = loaded[robot]
    for t in (run.controls.t, run.detections.t, run.groundtruth.t):
        assert np.all(np.diff(t) >= 0)
    assert report.odometry_out_of_order == 0  # Dataset 7 is already in time order
    theta = run.groundtruth.pose[:, 2]
    assert np.all((theta >= -math.pi) & (theta < math.pi))


@pytest.mark.parametrize("robot", ROBOTS)
def test_nominal_start_is_groundtruth_at_first_odometry(
    mrclam7: Path, loaded: dict, robot: int
) -> None:
    run, report = loaded[robot]
    path = mrclam7 / f"Robot{robot}_Groundtruth.dat"
    t0 = float(data_lines(mrclam7 / f"Robot{robot}_Odometry.dat")[0].split()[0])
    k = bisect.bisect_right(column(path, 0), t0)
    before, after = data_lines(path)[k - 1 : k + 1]
    (ta, xa, ya, tha), (tb, xb, yb, thb) = ([float(x) for x in r.split()] for r in (before, after))
    f = (t0 - ta) / (tb - ta)
    dth = (thb - tha + math.pi) % (2 * math.pi) - math.pi
    expected = [xa + f * (xb - xa), ya + f * (yb - ya), tha + f * dth]
    expected[2] = (expected[2] + math.pi) % (2 * math.pi) - math.pi
    assert report.start_time == t0
    assert report.start_inside_groundtruth
    np.testing.assert_allclose(run.meta.nominal_start, expected, atol=1e-9)


def test_meta_and_tag_map(mrclam7: Path, loaded: dict) -> None:
    run, _ = loaded[2]
    meta = run.meta
    assert meta.name == "mrclam7-robot2"
    assert meta.source == "recorded"
    assert meta.robot is None
    assert meta.control_rate_hz is None and meta.camera_rate_hz is None
    landmarks = data_rows(mrclam7 / "Landmark_Groundtruth.dat")
    assert sorted(meta.tag_map) == list(range(6, 21))
    for row in landmarks:
        np.testing.assert_array_equal(meta.tag_map[int(row[0])], [float(row[1]), float(row[2])])


def test_interpolation_unwraps_the_heading() -> None:
    t = np.array([0.0, 1.0, 2.0])
    pose = np.array([[0.0, 0.0, 3.0], [1.0, 2.0, -3.0], [2.0, 4.0, -2.9]])
    mid = interpolate_pose(t, pose, 0.5)
    # 3.0 -> -3.0 is a 0.283 rad turn through ±π, not a 6 rad turn through 0
    np.testing.assert_allclose(mid[:2], [0.5, 1.0])
    assert abs(abs(mid[2]) - math.pi) < 1e-12
    np.testing.assert_allclose(interpolate_pose(t, pose, 1.5), [1.5, 3.0, -2.95])
    np.testing.assert_allclose(interpolate_pose(t, pose, 9.0), pose[-1])


# ---- copies in tmp_path -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def first_lines(mrclam7: Path) -> dict[str, bytes]:
    """The first 1,000 lines of each Dataset 7 file, byte for byte (CRLF kept).

    A robot's measurements are cut where its first 1,000 odometry lines end, so that the
    files still share one time span (the loader refuses measurements beyond the odometry).
    """
    out = {}
    for src in mrclam7.glob("*.dat"):
        lines = src.read_bytes().split(b"\r\n")[:1000]
        out[src.name] = lines
    for name in [n for n in out if n.endswith("_Odometry.dat")]:
        end = float(out[name][-1].split()[0])
        kept = out[name.replace("Odometry", "Measurement")]
        kept[:] = [ln for ln in kept if ln.startswith(b"#") or float(ln.split()[0]) <= end]
    return {name: b"\r\n".join(lines) + b"\r\n" for name, lines in out.items()}


@pytest.fixture
def small(first_lines: dict[str, bytes], tmp_path: Path) -> Path:
    """A writable Dataset 7 folder of truncated copies, for breaking on purpose."""
    folder = tmp_path / "MRCLAM_Dataset7"
    folder.mkdir()
    for name, data in first_lines.items():
        (folder / name).write_bytes(data)
    return folder


def replace_line(path: Path, number: int, text: bytes) -> None:
    lines = path.read_bytes().split(b"\r\n")
    lines[number - 1] = text
    path.write_bytes(b"\r\n".join(lines))


def test_crlf_and_lf_load_the_same(mrclam7: Path, small: Path) -> None:
    assert b"\r\n" in (mrclam7 / "Robot1_Odometry.dat").read_bytes()[:200]
    crlf, _ = load_mrclam(small, 1)
    for path in small.glob("*.dat"):
        path.write_bytes(path.read_bytes().replace(b"\r\n", b"\n").replace(b"\t", b"  "))
    lf, _ = load_mrclam(small, 1)
    np.testing.assert_array_equal(crlf.controls.values, lf.controls.values)
    np.testing.assert_array_equal(crlf.detections.bearing, lf.detections.bearing)
    np.testing.assert_array_equal(crlf.groundtruth.pose, lf.groundtruth.pose)


def test_out_of_order_rows_are_sorted_and_duplicates_kept(small: Path) -> None:
    path = small / "Robot1_Odometry.dat"
    lines = path.read_bytes().split(b"\r\n")
    # move line 20 to after line 30 (out of order), and give lines 40 and 41 the same time
    t40 = lines[39].split()[0]
    lines[40] = b" ".join([t40, b"0.5", b"0.25"])
    lines[39] = b" ".join([t40, b"0.125", b"0.0"])
    lines.insert(30, lines.pop(19))
    path.write_bytes(b"\r\n".join(lines))
    # the moved line steps back a fraction of a second: sorted, counted, and warned about by line
    with pytest.warns(
        UserWarning,
        match=r"Robot1_Odometry.dat:31: 1 row\(s\) out of time order \(at most 0\.\d+ s",
    ):
        run, report = load_mrclam(small, 1)
    assert report.odometry_out_of_order == 1
    assert report.odometry_rows == len(data_rows(path))
    assert np.all(np.diff(run.controls.t) >= 0)
    i = int(np.flatnonzero(run.controls.t == float(t40))[0])
    assert run.controls.t[i + 1] == float(t40)
    assert (run.controls.values[i, 0], run.controls.values[i + 1, 0]) == (0.125, 0.5)
    assert report.odometry_duplicate_times == 1


MALFORMED = [
    ("Robot1_Odometry.dat", 10, b"1248446188.95 0.1", "expected 3 columns"),
    ("Robot1_Odometry.dat", 11, b"1248446188.95 0.1 0.2 0.3", "found 4"),
    ("Robot1_Odometry.dat", 12, b"1248446188.95 abc 0.2", "v is 'abc', not a number"),
    ("Robot1_Odometry.dat", 13, b"1248446188.95 0.1 1e999", "too large"),
    ("Robot1_Groundtruth.dat", 14, b"1248446182.2 nan 4.2 -1.7", "x is nan, not a finite"),
    ("Robot1_Groundtruth.dat", 15, b"1248446182.2 2.2 4.2 \xff", "not text"),
    ("Robot1_Measurement.dat", 16, b"1248446190.0 -inf 1.0 0.1", "barcode is -inf"),
    ("Robot1_Measurement.dat", 17, b"1248446190.0 61 -0.5 0.1", "negative range -0.5"),
    ("Robot1_Measurement.dat", 18, b"1248446190.0 61.5 1.0 0.1", "barcode 61.5 is not a whole"),
    ("Robot1_Measurement.dat", 19, b"1248446190.0 61 1.0 45.0", "45.0 rad is outside [-pi, pi]"),
    ("Robot1_Measurement.dat", 20, b"1248446190.0 61 1.0 -3.2", "(degrees?)"),
    ("Barcodes.dat", 12, b" 8 \t 63", "barcode 63 is mapped twice"),
    ("Barcodes.dat", 13, b" 1 \t 99", "subject 1 has two barcodes"),
    ("Landmark_Groundtruth.dat", 9, b" 6 1 2 0 0", "landmark 6 is listed twice"),
]


@pytest.mark.parametrize(("name", "line", "text", "problem"), MALFORMED)
def test_malformed_line_is_named(small: Path, name: str, line: int, text: bytes, problem: str):
    path = small / name
    replace_line(path, line, text)
    with pytest.raises(InputError) as caught:
        load_mrclam(small, 1)
    error = caught.value
    assert (Path(error.path), error.line) == (path, line)
    assert problem in error.problem
    assert str(error).startswith(f"{path}:{line}: ")


def test_line_numbers_count_comment_lines(small: Path) -> None:
    path = small / "Robot1_Odometry.dat"
    lines = path.read_bytes().split(b"\r\n")
    lines[6:6] = [b"# a comment in the middle", b""]
    lines[20] = b"bad 0 0"
    path.write_bytes(b"\r\n".join(lines))
    with pytest.raises(InputError) as caught:
        load_mrclam(small, 1)
    assert caught.value.line == 21


@pytest.mark.parametrize("content", [b"", b"# header only\r\n# Time [s]\r\n"])
def test_empty_file(small: Path, content: bytes) -> None:
    path = small / "Robot1_Measurement.dat"
    path.write_bytes(content)
    with pytest.raises(InputError, match="empty file") as caught:
        load_mrclam(small, 1)
    assert Path(caught.value.path) == path


def test_missing_file_names_it_and_the_robot(small: Path) -> None:
    (small / "Robot4_Odometry.dat").unlink()
    with pytest.raises(InputError) as caught:
        load_mrclam(small, 4)
    assert caught.value.path.endswith("Robot4_Odometry.dat")
    assert "robot 4" in caught.value.problem and "Robot4_Odometry.dat" in caught.value.problem
    load_mrclam(small, 3)  # other robots are unaffected


def test_without_groundtruth_the_robot_starts_at_the_origin(small: Path) -> None:
    """Datasets 1 and 4 come without Robot*_Groundtruth.dat: a run without truth, not an error."""
    with_truth, _ = load_mrclam(small, 4)
    (small / "Robot4_Groundtruth.dat").unlink()
    run, report = load_mrclam(small, 4)
    assert run.groundtruth is None and run.meta.nominal_start.tolist() == [0.0, 0.0, 0.0]
    assert len(run.detections.t) == len(with_truth.detections.t) > 0
    assert report.groundtruth_rows == 0 and report.groundtruth_first_time is None
    assert not report.start_inside_groundtruth
    assert report.as_dict()["loaded"]["groundtruth_span_s"] is None
    assert "no ground truth (no Robot*_Groundtruth.dat)" in report.lines()[0]


@pytest.mark.parametrize("robot", [0, 6, -1, True, 2.0])
def test_robot_outside_1_to_5(small: Path, robot) -> None:
    with pytest.raises(InputError, match="robot must be 1 to 5"):
        load_mrclam(small, robot)


def test_missing_folder(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not a folder"):
        load_mrclam(tmp_path / "nope", 1)


def test_start_outside_groundtruth_is_reported(small: Path) -> None:
    path = small / "Robot1_Groundtruth.dat"
    lines = path.read_bytes().split(b"\r\n")
    path.write_bytes(b"\r\n".join(lines[:104]))  # 100 rows: 1.6 s, ending before odometry starts
    run, report = load_mrclam(small, 1)
    assert not report.start_inside_groundtruth
    assert "clamped" in report.summary()
    np.testing.assert_allclose(run.meta.nominal_start, run.groundtruth.pose[-1])


def test_a_sighted_landmark_without_a_true_position_is_named_at_its_line(small: Path) -> None:
    measurements = small / "Robot1_Measurement.dat"
    barcode = int(data_rows(measurements)[0][1])  # the first sighting's barcode
    subject = barcode_table(small)[barcode]
    path = small / "Landmark_Groundtruth.dat"
    kept = [ln for ln in path.read_bytes().split(b"\r\n") if ln.split()[:1] != [b"%d" % subject]]
    path.write_bytes(b"\r\n".join(kept))
    with pytest.raises(InputError) as caught:
        load_mrclam(small, 1)
    first = next(
        i for i, ln in enumerate(measurements.read_text().splitlines(), 1) if not ln.startswith("#")
    )
    assert (Path(caught.value.path), caught.value.line) == (measurements, first)
    assert f"landmark {subject} (barcode {barcode}" in caught.value.problem
    assert "Landmark_Groundtruth.dat" in caught.value.problem


def test_measurements_on_another_clock_are_refused(small: Path) -> None:
    path = small / "Robot1_Measurement.dat"
    text = path.read_bytes().replace(b"124844", b"224844")  # 100 million s later
    path.write_bytes(text)
    with pytest.raises(InputError, match="different clocks") as caught:
        load_mrclam(small, 1)
    assert Path(caught.value.path) == path and "Robot1_Odometry.dat" in caught.value.problem
