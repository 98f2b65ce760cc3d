"""Bad data through the command line, one row per defect: run folders, run.json variants, MRCLAM
folders, ROS bag inputs and runs logged as camera frames.

Every row must end with exit status 2, ONE line on stderr that names the input the user gave
(the file, and the line where there is one, or the option) and says what is wrong, and no
traceback. The rows run as concurrent subprocesses from one fixture (as in test_bad_input.py).
MRCLAM rows are built from truncated copies of the real Dataset 7 files and skip without them.
"""

from __future__ import annotations

import json
import os
import random
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from ekfslam import SimulationConfig, simulate, write_run

REPO = Path(__file__).resolve().parents[2]
FRAMES_RUN = REPO / "data" / "runs" / "square-1lap-frames"

pytestmark = pytest.mark.slow


@dataclass(frozen=True)
class Case:
    """build(folder) makes the input in `folder` and returns (argv after `-m ekfslam`, where):
    `where` is what the error line must name, e.g. ``.../detections.csv:2``."""

    build: Callable[[Path], tuple[list[str], str]]
    word: str  # the error must say this (case-insensitive)
    mrclam: bool = False  # needs the shared MRCLAM data


# ---------------------------------------------------------------------------------------------
# Run folders of our format


def _clean(folder: Path) -> Path:
    run = simulate(SimulationConfig(trajectory="square", laps=1, seed=1))
    return write_run(run, folder)


def _csv_times(name: str, edit: Callable[[float], float]) -> Callable[[Path], tuple]:
    def build(folder: Path) -> tuple[list[str], str]:
        _clean(folder)
        lines = (folder / name).read_text().splitlines()
        for i in range(1, len(lines)):
            t, rest = lines[i].split(",", 1)
            lines[i] = f"{edit(float(t))!r},{rest}"
        (folder / name).write_text("\n".join(lines) + "\n")
        return ["run", str(folder)], f"{folder / name}:2"

    return build


def _epoch_ns(t: float) -> float:
    return (t + 1.7e9) * 1e9  # a ROS stamp in nanoseconds beside controls in seconds from 0


def _run_json(edit: Callable[[dict], None] | None = None, text=None) -> Callable[[Path], tuple]:
    """A run whose run.json is edited as a dict, or rewritten by text(old text)."""

    def build(folder: Path) -> tuple[list[str], str]:
        _clean(folder)
        path = folder / "run.json"
        if edit is not None:
            doc = json.loads(path.read_text())
            edit(doc)
            path.write_text(json.dumps(doc, indent=2))
        if text is not None:
            path.write_text(text(path.read_text()))
        return ["run", str(folder)], f"{path}:"

    return build


def _start(value: str) -> Callable[[str], str]:
    def text(old: str) -> str:
        doc = json.loads(old)
        doc["nominal_start"] = "START"
        return json.dumps(doc, indent=2).replace('"START"', value)

    return text


def _replace_file(name: str, make: Callable[[Path], None]) -> Callable[[Path], tuple]:
    def build(folder: Path) -> tuple[list[str], str]:
        _clean(folder)
        (folder / name).unlink()
        make(folder / name)
        return ["run", str(folder)], str(folder / name)

    return build


def _empty_folder(folder: Path) -> tuple[list[str], str]:
    folder.mkdir()
    return ["run", str(folder)], str(folder)


def _tag_map_id(doc: dict) -> None:
    doc["tag_map"]["99999999999999999999"] = doc["tag_map"].pop("0")


def _deep(old: str) -> str:
    doc = json.loads(old)
    doc["simulation"] = "DEEP"
    return json.dumps(doc, indent=2).replace('"DEEP"', "[" * 100_000)


RUNS: dict[str, Case] = {
    "detections in ns, controls in s": Case(
        _csv_times("detections.csv", _epoch_ns), "different clocks"
    ),
    "detections 5 s before the controls": Case(
        _csv_times("detections.csv", lambda t: t - 5.0), "outside"
    ),
    "ground truth on another clock": Case(
        _csv_times("groundtruth.csv", lambda t: t + 1e9), "groundtruth.csv"
    ),
    "nominal_start 1e308": Case(_run_json(text=_start("[1e308, 0.0, 0.0]")), "plausible"),
    "nominal_start heading in degrees": Case(_run_json(text=_start("[0.0, 0.0, 90.0]")), "degrees"),
    "nominal_start integer beyond a float": Case(
        _run_json(text=_start(f"[1{'0' * 400}, 0, 0]")), "finite numbers"
    ),
    "a 5,000-digit integer": Case(_run_json(text=_start(f"[{'9' * 5000}, 0, 0]")), "digits"),
    "tag id beyond int64": Case(_run_json(_tag_map_id), "64 bits"),
    "100,000-deep nesting": Case(_run_json(text=_deep), "nested too deeply"),
    "a folder named run.json": Case(_replace_file("run.json", Path.mkdir), "is a folder"),
    "run.json a symlink loop": Case(
        _replace_file("run.json", lambda p: p.symlink_to(p)), "symbolic link"
    ),
    "run.json a dangling symlink": Case(
        _replace_file("run.json", lambda p: p.symlink_to(p.parent / "gone.json")), "symbolic link"
    ),
    "a folder named controls.csv": Case(_replace_file("controls.csv", Path.mkdir), "folder"),
    "an empty folder": Case(_empty_folder, "no run.json (our run format) and no Barcodes.dat"),
}


# ---------------------------------------------------------------------------------------------
# MRCLAM folders with one defect each (built from the shared Dataset 7, robot 1)

MRCLAM_SOURCE: list[Path] = []  # the Dataset 7 folder, once the fixture has found it


def _small_mrclam(folder: Path) -> Path:
    """Robot 1's first 400 odometry lines, its measurements and truth up to then, CRLF kept."""
    src = MRCLAM_SOURCE[0]
    folder.mkdir()
    for name in ("Barcodes.dat", "Landmark_Groundtruth.dat"):
        shutil.copy(src / name, folder / name)
    odometry = (src / "Robot1_Odometry.dat").read_bytes().split(b"\r\n")[:400]
    end = float(odometry[-1].split()[0])
    (folder / "Robot1_Odometry.dat").write_bytes(b"\r\n".join(odometry) + b"\r\n")
    for kind in ("Measurement", "Groundtruth"):
        lines = (src / f"Robot1_{kind}.dat").read_bytes().split(b"\r\n")
        kept = [ln for ln in lines if ln.startswith(b"#") or (ln and float(ln.split()[0]) <= end)]
        (folder / f"Robot1_{kind}.dat").write_bytes(b"\r\n".join(kept) + b"\r\n")
    return folder


def _measurement_lines(folder: Path) -> list[bytes]:
    return (folder / "Robot1_Measurement.dat").read_bytes().split(b"\r\n")


def _subjects(folder: Path) -> dict[int, int]:
    rows = [ln.split() for ln in (folder / "Barcodes.dat").read_bytes().splitlines()]
    return {int(b): int(s) for s, b, *_ in (r for r in rows if r and not r[0].startswith(b"#"))}


def _first_landmark_sighting(folder: Path) -> int:
    """Index into _measurement_lines of the first sighting of a landmark (not a robot)."""
    subjects = _subjects(folder)
    for i, line in enumerate(_measurement_lines(folder)):
        if line and not line.startswith(b"#") and subjects.get(int(line.split()[1]), 0) >= 6:
            return i
    raise AssertionError("no landmark sighting")


def _mrclam(command: str, defect: Callable[[Path], str]) -> Callable[[Path], tuple]:
    """`defect` breaks the small dataset and returns what the error must name."""

    def build(folder: Path) -> tuple[list[str], str]:
        where = defect(_small_mrclam(folder))
        if command == "run":
            return ["run", str(folder), "--robot", "1"], where
        out = folder.parent / f"{folder.name}-out"
        return ["convert", "mrclam", str(folder), "--robot", "1", "--out", str(out)], where

    return build


def _bearing_in_degrees(folder: Path) -> str:
    lines = _measurement_lines(folder)
    i = _first_landmark_sighting(folder)
    t, barcode, rng, _ = lines[i].split()
    lines[i] = b" ".join([t, barcode, rng, b"45.0"])
    (folder / "Robot1_Measurement.dat").write_bytes(b"\r\n".join(lines))
    return f"{folder / 'Robot1_Measurement.dat'}:{i + 1}"


def _landmark_without_truth(folder: Path) -> str:
    i = _first_landmark_sighting(folder)
    subject = _subjects(folder)[int(_measurement_lines(folder)[i].split()[1])]
    path = folder / "Landmark_Groundtruth.dat"
    kept = [ln for ln in path.read_bytes().split(b"\r\n") if ln.split()[:1] != [b"%d" % subject]]
    path.write_bytes(b"\r\n".join(kept))
    return f"{folder / 'Robot1_Measurement.dat'}:{i + 1}"


def _measurements_in_ns(folder: Path) -> str:
    path = folder / "Robot1_Measurement.dat"
    lines = []
    for ln in path.read_bytes().split(b"\r\n"):
        if ln and not ln.startswith(b"#"):
            t, rest = ln.split(None, 1)
            ln = b"%d " % int(float(t) * 1e9) + rest
        lines.append(ln)
    path.write_bytes(b"\r\n".join(lines))
    return str(path)


def _delete(name: str) -> Callable[[Path], str]:
    def defect(folder: Path) -> str:
        (folder / name).unlink()
        return str(folder / name)

    return defect


def _only(*names: str) -> Callable[[Path], str]:
    def defect(folder: Path) -> str:
        for path in folder.iterdir():
            if path.name not in names:
                path.unlink()
        return str(folder / "Barcodes.dat")

    return defect


def _negative_range(folder: Path) -> str:
    lines = _measurement_lines(folder)
    i = _first_landmark_sighting(folder)
    t, barcode, _, bearing = lines[i].split()
    lines[i] = b" ".join([t, barcode, b"-0.5", bearing])
    (folder / "Robot1_Measurement.dat").write_bytes(b"\r\n".join(lines))
    return f"{folder / 'Robot1_Measurement.dat'}:{i + 1}"


MRCLAM: dict[str, Case] = {
    "MRCLAM without Barcodes.dat": Case(
        _mrclam("run", _delete("Barcodes.dat")), "missing", mrclam=True
    ),
    "MRCLAM odometry files only": Case(
        _mrclam("run", _only("Robot1_Odometry.dat")), "MRCLAM", mrclam=True
    ),
    "MRCLAM without Landmark_Groundtruth.dat": Case(
        _mrclam("run", _delete("Landmark_Groundtruth.dat")), "not found", mrclam=True
    ),
    "MRCLAM bearing in degrees": Case(_mrclam("run", _bearing_in_degrees), "degrees", mrclam=True),
    "MRCLAM landmark without a true position": Case(
        _mrclam("run", _landmark_without_truth), "Landmark_Groundtruth.dat", mrclam=True
    ),
    "MRCLAM measurements in ns": Case(
        _mrclam("run", _measurements_in_ns), "different clocks", mrclam=True
    ),
    "MRCLAM negative range": Case(_mrclam("run", _negative_range), "negative", mrclam=True),
    "convert mrclam, bearing in degrees": Case(
        _mrclam("convert", _bearing_in_degrees), "degrees", mrclam=True
    ),
    "convert mrclam, landmark without a true position": Case(
        _mrclam("convert", _landmark_without_truth), "Landmark_Groundtruth.dat", mrclam=True
    ),
}


# ---------------------------------------------------------------------------------------------
# ROS bag inputs (every check here runs before a message is read)


def _rosbag(*options: str, bag: Callable[[Path], Path] | None = None) -> Callable[[Path], tuple]:
    def build(folder: Path) -> tuple[list[str], str]:
        folder.mkdir()
        path = bag(folder) if bag is not None else _fake_ros2_bag(folder)
        argv = ["convert", "rosbag", str(path), "--out", str(folder / "out")]
        argv += ["--twist-topic", "/odom", "--detections-topic", "/tf", *options]
        return argv, f"{path}: "

    return build


def _fake_ros2_bag(folder: Path) -> Path:
    (folder / "bag").mkdir()
    (folder / "bag" / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    return folder / "bag"


def _plain_folder(folder: Path) -> Path:
    (folder / "photos").mkdir()
    (folder / "photos" / "a.txt").write_text("not a bag\n")
    return folder / "photos"


def _text_file(folder: Path) -> Path:
    (folder / "notes.bag").write_text("not a bag\n")
    return folder / "notes.bag"


ROSBAGS: dict[str, Case] = {
    "rosbag: a plain folder": Case(_rosbag(bag=_plain_folder), "metadata.yaml"),
    "rosbag: a text file named .bag": Case(_rosbag(bag=_text_file), "cannot read the bag"),
    "rosbag: --start nan": Case(_rosbag("--start", "nan", "0", "0"), "--start"),
    "rosbag: --start 1e308": Case(_rosbag("--start", "1e308", "0", "0"), "--start"),
    "rosbag: --camera-mounting inf": Case(
        _rosbag("--camera-mounting", "0", "inf", "0"), "--camera-mounting"
    ),
    "rosbag: pattern without a group": Case(_rosbag("--tag-frame-pattern", r"tag_\d+"), "group 1"),
    "rosbag: pattern whose group 1 is not digits": Case(
        _rosbag("--tag-frame-pattern", r"(tag)_\d+"), "group 1"
    ),
    "rosbag: pattern that does not compile": Case(
        _rosbag("--tag-frame-pattern", r"tag_(\d+"), "regular expression"
    ),
}


# ---------------------------------------------------------------------------------------------
# Runs logged as camera frames


def _damaged_video(folder: Path) -> tuple[list[str], str]:
    shutil.copytree(FRAMES_RUN, folder)
    video = folder / "frames.mp4"
    data = bytearray(video.read_bytes())
    rng = random.Random(1)
    for i in range(200_000, len(data), 997):  # junk through the mdat after the first frames
        data[i] = rng.randrange(256)
    video.write_bytes(bytes(data))
    return ["run", str(folder)], str(video)


def _truncated_video(folder: Path) -> tuple[list[str], str]:
    shutil.copytree(FRAMES_RUN, folder)
    video = folder / "frames.mp4"
    video.write_bytes(video.read_bytes()[:5000])
    return ["run", str(folder)], str(video)


FRAMES: dict[str, Case] = {
    "frames: damaged video": Case(_damaged_video, "video"),
    "frames: truncated video": Case(_truncated_video, "video"),
}

CASES: dict[str, Case] = RUNS | MRCLAM | ROSBAGS | FRAMES


@pytest.fixture(scope="module")
def outcomes(request, tmp_path_factory) -> dict[str, tuple[subprocess.CompletedProcess, str]]:
    """Every case's finished process and what its error must name, all run concurrently."""
    try:
        MRCLAM_SOURCE[:] = [request.getfixturevalue("mrclam7")]
    except pytest.skip.Exception:
        MRCLAM_SOURCE.clear()  # the MRCLAM rows skip; the others still run
    root = tmp_path_factory.mktemp("bad-data")
    env = {**os.environ, "MPLBACKEND": "Agg"}
    started = {}
    for i, (name, case) in enumerate(CASES.items()):
        if case.mrclam and not MRCLAM_SOURCE:
            continue
        argv, where = case.build(root / f"case{i:02d}")
        proc = subprocess.Popen(
            [sys.executable, "-m", "ekfslam", *argv],
            cwd=REPO,
            env=env,
            text=True,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        started[name] = (proc, where)
    done = {}
    for name, (proc, where) in started.items():
        out, err = proc.communicate(timeout=600)
        done[name] = (subprocess.CompletedProcess(proc.args, proc.returncode, out, err), where)
    return done


def test_the_table_is_big_enough():
    assert len(CASES) >= 25


def _param(name: str):
    marks = [pytest.mark.shared_data] if CASES[name].mrclam else []
    return pytest.param(name, marks=marks, id=name)


@pytest.mark.parametrize("name", [_param(n) for n in CASES])
def test_bad_data_ends_in_one_line_naming_the_input(outcomes, name):
    if name not in outcomes:
        pytest.skip("needs the shared MRCLAM Dataset 7")
    out, where = outcomes[name]
    assert "Traceback" not in out.stderr, out.stderr[-2000:]
    assert out.returncode == 2, (out.stdout, out.stderr[-2000:])
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr[-2000:]  # nothing from OpenCV, FFmpeg or numpy
    # a bad option value is refused by the parser, which names the option the user typed;
    # everything else names the input file (and line)
    refused_option = lines[0].startswith("python -m ekfslam ") and ": error: argument " in lines[0]
    assert lines[0].startswith("error: ") or refused_option, lines[0]
    assert refused_option or where in lines[0], lines[0]
    assert CASES[name].word.lower() in lines[0].lower(), lines[0]
    assert "detections.csv:" not in lines[0] or "detections.csv" in where  # not a file never given
    assert len(lines[0]) < 600, lines[0]  # a 5,000-digit number is not echoed whole
