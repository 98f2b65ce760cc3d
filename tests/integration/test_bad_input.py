"""Malformed logs through the command line, as a user meets them.

Every broken log must end with ONE line on stderr that names the file (and the line, where there
is one), exit status 2, and no traceback. Harmless quirks of other editors (a UTF-8 byte-order
mark, Windows line endings) must be accepted and replay exactly like the clean log.

All the cases run as concurrent subprocesses (`python -m ekfslam run DIR`) from one fixture, so
the file costs about one interpreter start per core, not one per case.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from ekfslam import SimulationConfig, simulate, write_run

REPO = Path(__file__).resolve().parents[2]


def _edit_line(name: str, line: int, edit: Callable[[str], str]) -> Callable[[Path], None]:
    """A mutation that rewrites 1-based `line` of one file of the run."""

    def mutate(folder: Path) -> None:
        lines = (folder / name).read_text().split("\n")
        lines[line - 1] = edit(lines[line - 1])
        (folder / name).write_text("\n".join(lines))

    return mutate


def _field(index: int, value: str) -> Callable[[str], str]:
    def edit(row: str) -> str:
        cells = row.split(",")
        cells[index] = value
        return ",".join(cells)

    return edit


def _write(name: str, text: str | bytes) -> Callable[[Path], None]:
    def mutate(folder: Path) -> None:
        path = folder / name
        path.write_bytes(text) if isinstance(text, bytes) else path.write_text(text)

    return mutate


def _delete(name: str) -> Callable[[Path], None]:
    return lambda folder: (folder / name).unlink()


def _json_edit(old: str, new: str) -> Callable[[Path], None]:
    def mutate(folder: Path) -> None:
        text = (folder / "run.json").read_text()
        assert old in text, old
        (folder / "run.json").write_text(text.replace(old, new, 1))

    return mutate


def _insert_line(name: str, line: int, text: str | None = None) -> Callable[[Path], None]:
    def mutate(folder: Path) -> None:
        lines = (folder / name).read_text().split("\n")
        lines.insert(line - 1, lines[0] if text is None else text)
        (folder / name).write_text("\n".join(lines))

    return mutate


def _bad_byte(name: str, line: int) -> Callable[[Path], None]:
    def mutate(folder: Path) -> None:
        lines = (folder / name).read_bytes().split(b"\n")
        lines[line - 1] = lines[line - 1].replace(b".", b"\xff.", 1)  # Latin-1 junk, not UTF-8
        (folder / name).write_bytes(b"\n".join(lines))

    return mutate


#: name -> (mutation, where the error must point: "file:line:" or just "file", a word it must say)
BROKEN: dict[str, tuple[Callable[[Path], None], str, str]] = {
    "truncated line": (
        _edit_line("controls.csv", 6, lambda r: r.rsplit(",", 1)[0]),
        "controls.csv:6:",
        "truncated",
    ),
    "missing column": (
        _edit_line("detections.csv", 1, lambda r: "t,tag_id,range"),
        "detections.csv:1:",
        "bearing",
    ),
    "text in a number": (
        _edit_line("detections.csv", 4, _field(2, "abc")),
        "detections.csv:4:",
        "abc",
    ),
    "NaN": (_edit_line("controls.csv", 7, _field(2, "nan")), "controls.csv:7:", "nan"),
    "inf": (_edit_line("detections.csv", 5, _field(3, "inf")), "detections.csv:5:", "inf"),
    "time backwards": (
        _edit_line("controls.csv", 9, _field(0, "0.01")),
        "controls.csv:9:",
        "earlier",
    ),
    "duplicate header": (_insert_line("controls.csv", 10), "controls.csv:10:", "header"),
    "blank line": (_insert_line("controls.csv", 8, ""), "controls.csv:8:", "blank"),
    "empty file": (_write("detections.csv", ""), "detections.csv:1:", "empty"),
    "header only": (_write("controls.csv", "t,w1,w2,w3,w4\n"), "controls.csv:2:", "no controls"),
    "wrong format version": (
        _json_edit('"format_version": 1', '"format_version": 2'),
        "run.json:3:",
        "format_version",
    ),
    "invalid JSON": (
        _json_edit('"source": "simulated",', '"source": "simulated",,'),
        "run.json:5:",
        "JSON",
    ),
    "duplicate key": (
        _json_edit('"source": "simulated",', '"source": "simulated", "name": "x",'),
        "run.json:5:",
        "twice",
    ),
    "angles in degrees (units)": (
        _json_edit('"angle": "rad"', '"angle": "deg"'),
        "run.json:6:",
        "units",
    ),
    "negative range": (
        _edit_line("detections.csv", 3, _field(2, "-0.5")),
        "detections.csv:3:",
        "negative",
    ),
    "bearing in degrees": (
        _edit_line("detections.csv", 6, _field(3, "45.0")),
        "detections.csv:6:",
        "degrees",
    ),
    "unknown tag id": (_edit_line("detections.csv", 7, _field(1, "99")), "detections.csv:7:", "99"),
    "tag id not an integer": (
        _edit_line("detections.csv", 8, _field(1, "2.5")),
        "detections.csv:8:",
        "integer",
    ),
    "ground truth NaN": (
        _edit_line("groundtruth.csv", 4, _field(1, "nan")),
        "groundtruth.csv:4:",
        "nan",
    ),
    "not UTF-8": (_bad_byte("detections.csv", 5), "detections.csv:5:", "UTF-8"),
    "missing run.json": (_delete("run.json"), "run.json", "missing"),
    "missing controls.csv": (_delete("controls.csv"), "controls.csv", "missing"),
}


def _bom(folder: Path) -> None:
    for path in folder.iterdir():
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())


def _crlf(folder: Path) -> None:
    for path in folder.iterdir():
        path.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))


ACCEPTED: dict[str, Callable[[Path], None]] = {
    "clean": lambda folder: None,
    "BOM": _bom,
    "CRLF": _crlf,
    "BOM and CRLF": lambda folder: (_bom(folder), _crlf(folder)),
}


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory) -> dict[str, tuple[subprocess.CompletedProcess, Path]]:
    """Every case's finished process and its run folder, all run concurrently."""
    root = tmp_path_factory.mktemp("bad-input")
    clean = write_run(simulate(SimulationConfig(trajectory="square", laps=1, seed=1)), root / "c")
    env = {**os.environ, "MPLBACKEND": "Agg"}
    cases = {name: spec[0] for name, spec in BROKEN.items()} | ACCEPTED
    started = {}
    for i, (name, mutate) in enumerate(cases.items()):
        folder = shutil.copytree(clean, root / f"case{i:02d}")
        mutate(folder)
        json_flag = ["--json"] if name in ACCEPTED else []
        started[name] = (
            subprocess.Popen(
                [sys.executable, "-m", "ekfslam", "run", str(folder), *json_flag],
                cwd=REPO,
                env=env,
                text=True,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
            ),
            folder,
        )
    done = {}
    for name, (proc, folder) in started.items():
        out, err = proc.communicate(timeout=600)
        done[name] = (subprocess.CompletedProcess(proc.args, proc.returncode, out, err), folder)
    return done


def test_the_matrix_is_big_enough():
    assert len(BROKEN) >= 15


@pytest.mark.slow
@pytest.mark.parametrize("name", list(BROKEN))
def test_broken_log_ends_in_one_line_naming_file_and_line(outcomes, name):
    out, folder = outcomes[name]
    _, where, word = BROKEN[name]
    assert out.returncode == 2, (out.stdout, out.stderr)
    assert "Traceback" not in out.stderr
    assert out.stdout == ""
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    assert lines[0].startswith("error: ")
    assert f"{folder}/{where}" in lines[0], lines[0]
    assert word.lower() in lines[0].lower(), lines[0]


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in ACCEPTED if n != "clean"])
def test_bom_and_crlf_replay_exactly_like_the_clean_log(outcomes, name):
    clean, quirky = outcomes["clean"][0], outcomes[name][0]
    assert clean.returncode == 0, clean.stderr
    assert quirky.returncode == 0, quirky.stderr
    a, b = json.loads(clean.stdout), json.loads(quirky.stdout)
    for d in (a, b):
        d.pop("seconds")
    assert a["updates"]["accepted"] > 100 and a["alignment"]["mean_error"] > 0
    assert a == b  # the same bits: every number, every count
