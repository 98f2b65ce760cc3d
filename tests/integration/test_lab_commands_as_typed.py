"""The lab's commands exactly as `notebooks/INSTRUCTOR.md` and `docs/guide/lab.md` type them, run
from a fresh folder as an instructor would: once with the environment activated (its ``bin`` first
on PATH, ``python`` found there) and once not (the environment's python named by its path, PATH
without it). Between release and grade the test does what the instructor does by hand: one
folder per student under ``submissions/`` (one student hands in the solved notebook 02, one the
release's).

The commands are read from the texts, not written here: a text that changes its command
changes what runs.
"""

from __future__ import annotations

import csv
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ekfslam.cli.lab_sandbox import unavailable

ROOT = Path(__file__).resolve().parents[2]
TEXTS = [ROOT / "notebooks" / "INSTRUCTOR.md", ROOT / "docs" / "guide" / "lab.md"]
BLOCK = re.compile(r"```bash\n(.*?)```", re.S)


def documented(path: Path, verb: str) -> list[str]:
    """Every ``python -m ekfslam lab VERB`` line of `path`'s bash blocks, comments cut."""
    lines = []
    for block in BLOCK.findall(path.read_text(encoding="utf-8")):
        for line in block.splitlines():
            line = line.split("  #", 1)[0].strip()
            if line.startswith(f"python -m ekfslam lab {verb} "):
                lines.append(line)
    return lines


def test_each_text_gives_a_release_and_a_grade_command() -> None:
    for path in TEXTS:
        assert documented(path, "release") and documented(path, "grade"), path


def _environments(home: Path) -> dict[str, tuple[dict[str, str], str]]:
    venv_bin = str(Path(sys.executable).parent)
    plain_path = os.pathsep.join(
        p for p in os.environ.get("PATH", "").split(os.pathsep) if p and p != venv_bin
    )
    base = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    base["HOME"] = str(home)
    activated = {**base, "PATH": venv_bin + os.pathsep + plain_path, "VIRTUAL_ENV": sys.prefix}
    return {
        "activated": (activated, "python"),
        "not activated": ({**base, "PATH": plain_path}, sys.executable),
    }


def run(line: str, python: str, env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess:
    argv = shlex.split(line)
    assert argv[0] == "python"
    return subprocess.run(
        [python, *argv[1:]] if python != "python" else argv,
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )


@pytest.mark.slow
@pytest.mark.parametrize("text", TEXTS, ids=lambda p: p.name)
@pytest.mark.parametrize("mode", ["activated", "not activated"])
def test_the_documented_commands_run_as_typed_from_a_fresh_folder(text, mode, tmp_path) -> None:
    if unavailable() is not None:
        pytest.skip(f"no sandbox on this machine: {unavailable()}")
    env, python = _environments(tmp_path / "home")[mode]
    (tmp_path / "home").mkdir()
    folder = tmp_path / "fresh"
    folder.mkdir()
    (release,) = documented(text, "release")
    (grade,) = documented(text, "grade")
    done = run(release, python, env, folder)
    assert done.returncode == 0, (release, done.stderr[-3000:])
    assert done.stderr == "", done.stderr
    handout = folder / shlex.split(release)[-1]
    course = folder / "lab-course"
    assert (handout / "02-robot-and-arena.ipynb").is_file() and (course / "key.pkl").is_file()
    submissions = folder / shlex.split(grade)[5]
    for student, source in (("alice", course / "source"), ("bob", handout)):
        (submissions / student).mkdir(parents=True)
        shutil.copy(source / "02-robot-and-arena.ipynb", submissions / student)
    done = run(grade, python, env, folder)
    assert done.returncode == 0, (grade, done.stderr[-3000:])
    # each student's line says what its sandboxes cost, as they reported it at their close
    cpu = dict(
        re.findall(r"^(\w+): total .* \(its sandboxes: ([0-9.]+) s CPU\)$", done.stdout, re.M)
    )
    assert set(cpu) == {"alice", "bob"} and float(cpu["alice"]) > 0.1, done.stdout
    csv_path = folder / shlex.split(grade)[shlex.split(grade).index("--csv") + 1]
    rows = {r["student"]: r for r in csv.DictReader(csv_path.open(encoding="utf-8"))}
    assert (rows["alice"]["1a"], rows["alice"]["1b"]) == ("1", "1"), rows["alice"]
    assert (rows["bob"]["1a"], rows["bob"]["1b"]) == ("0", "0"), rows["bob"]
    assert {r["sandbox"] for r in rows.values()} == {"bubblewrap"}
    feedback = csv_path.with_name(csv_path.stem + "-feedback")
    assert sorted(p.name for p in feedback.iterdir()) == ["alice.txt", "bob.txt"]
    # nothing else was written in the instructor's folder
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        {handout.name, course.name, submissions.name, csv_path.name, feedback.name}
    )


@pytest.mark.slow
def test_a_failed_release_leaves_nothing_behind_and_the_retry_works(tmp_path) -> None:
    """A release into a folder that exists fails in one line and writes no course; once the
    folder is gone the same command works."""
    (release,) = documented(TEXTS[0], "release")
    env, python = _environments(tmp_path / "home")["not activated"]
    folder = tmp_path / "fresh"
    (folder / "handout").mkdir(parents=True)
    (folder / "handout" / "mine.txt").write_text("the instructor's own file\n", encoding="utf-8")
    done = run(release, python, env, folder)
    assert done.returncode != 0 and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert "Traceback" not in done.stderr
    assert sorted(p.name for p in folder.iterdir()) == ["handout"]
    assert [p.name for p in (folder / "handout").iterdir()] == ["mine.txt"]
    shutil.rmtree(folder / "handout")
    done = run(release, python, env, folder)
    assert done.returncode == 0, done.stderr
