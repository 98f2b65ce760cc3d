"""The red team's corpus (`tests/integration/lab_attacks.py`) through ``lab grade``, as a course
would run it: one release of notebook 02, every attack a student of its own beside an honest
correct and an honest all-stubs student, all graded in one run.

Each attack must score what its honest work earns (0: its function returns the right twist only
when its attack worked), the honest students exactly what they earn, and every file outside the
grader's own outputs (the course, the submissions, the instructor's home and working folder,
the installed package) must be as it was, with no process of the submissions left running and
the CSV unchanged seconds after ``lab grade`` returned; no feedback holds a canary or a control
character."""

from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ekfslam.cli import lab_sandbox
from ekfslam.teaching.make_lab import SOLUTIONS
from tests.integration.lab_attacks import CORPUS

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK = "02-robot-and-arena.ipynb"
CANARY = "CANARY-" + "7f3a9c"
MARKER = "ATTACK-" + "51d0e2"
COLUMNS = ["1a", "1b", "predict-02"]


def _snapshot(*folders: Path) -> dict[str, str]:
    out = {}
    for folder in folders:
        for path in sorted(folder.rglob("*")):
            if path.is_file() and "__pycache__" not in path.parts:
                out[str(path)] = hashlib.sha256(path.read_bytes()).hexdigest()
    return out


def _answer_cell(nb: dict) -> dict:
    (cell,) = [
        c for c in nb["cells"] if c["metadata"].get("nbgrader", {}).get("grade_id") == "answer-1a"
    ]
    return cell


def _running(marker: str) -> list[str]:
    found = []
    for pid in os.listdir("/proc"):
        if pid.isdigit():
            try:
                cmd = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
            except OSError:
                continue
            if marker in cmd and "pytest" not in cmd:
                found.append(f"{pid}: {cmd[:120]}")
    return found


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    if lab_sandbox.unavailable() is not None:
        if os.environ.get("CI") == "true":
            pytest.fail(f"CI must grade in the sandbox: {lab_sandbox.unavailable()}")
        pytest.skip(f"no sandbox here: {lab_sandbox.unavailable()}")
    tmp = tmp_path_factory.mktemp("attacks")
    home, cwd = tmp / "home", tmp / "cwd"
    home.mkdir()
    cwd.mkdir()
    (home / "secret.txt").write_text(CANARY)
    (cwd / "notes.txt").write_text(CANARY)
    course, release, subs = cwd / "lab-course", cwd / "handout", cwd / "subs"
    env = {**os.environ, "HOME": str(home)}
    run = [sys.executable, "-m", "ekfslam", "lab"]
    subprocess.run(
        [*run, "release", "handout", "--notebooks", "02", "--seed", "9"],
        cwd=cwd,
        env=env,
        check=True,
        capture_output=True,
    )
    (course / "notes.txt").write_text(CANARY)
    stub = json.loads((release / NOTEBOOK).read_text(encoding="utf-8"))
    (subs / "honest-correct").mkdir(parents=True)
    (subs / "honest-correct" / NOTEBOOK).write_bytes((SOLUTIONS / NOTEBOOK).read_bytes())
    (subs / "honest-correct" / "lab-predictions.json").write_text(
        json.dumps({"02-wheels": "front-right and rear-left"})
    )
    (subs / "honest-stubs").mkdir()
    (subs / "honest-stubs" / NOTEBOOK).write_bytes((release / NOTEBOOK).read_bytes())
    names = {}
    csv_path = cwd / "grades.csv"
    fill = {
        "{COURSE}": str(course),
        "{SUBS}": str(subs),
        "{HOME}": str(home),
        "{CWD}": str(cwd),
        "{CSV}": str(csv_path),
        "{PACKAGE}": str(ROOT / "ekfslam"),
        "{CANARY}": CANARY,
        "{MARKER}": MARKER,
    }
    for i, (family, label, source) in enumerate(CORPUS):
        name = f"attack{i:02d}"
        names[name] = (family, label)
        for key, value in fill.items():
            source = source.replace(key, value)
        nb = json.loads(json.dumps(stub))
        _answer_cell(nb)["source"] = source.splitlines(keepends=True)
        (subs / name).mkdir()
        (subs / name / NOTEBOOK).write_text(json.dumps(nb), encoding="utf-8")
    (subs / "attack-links").mkdir()  # a submission of links to the key and a classmate
    (subs / "attack-links" / NOTEBOOK).symlink_to(subs / "honest-correct" / NOTEBOOK)
    (subs / "attack-links" / "lab-predictions.json").symlink_to(course / "key.pkl")
    before = _snapshot(course, subs, home, ROOT / "ekfslam")
    before_cwd = {k: v for k, v in _snapshot(cwd).items() if not k.startswith(str(course))}
    started = time.monotonic()
    done = subprocess.run(
        [*run, "grade", "subs", "--csv", "grades.csv", "--timeout", "20", "--jobs", "2"],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    seconds = time.monotonic() - started
    assert done.returncode == 0, done.stderr[-2000:]
    written = csv_path.read_text(encoding="utf-8")
    time.sleep(10)  # a detached process would rewrite the CSV by now
    return {
        "rows": {r["student"]: r for r in csv.DictReader(csv_path.open(encoding="utf-8"))},
        "names": names,
        "csv_then": written,
        "csv_now": csv_path.read_text(encoding="utf-8"),
        "before": before,
        "after": _snapshot(course, subs, home, ROOT / "ekfslam"),
        "before_cwd": before_cwd,
        "after_cwd": {
            k: v
            for k, v in _snapshot(cwd).items()
            if not k.startswith((str(course), str(cwd / "grades")))
        },
        "feedback": {
            p.stem: p.read_text(encoding="utf-8") for p in (cwd / "grades-feedback").glob("*.txt")
        },
        "seconds": seconds,
        "stdout": done.stdout,
    }


def test_the_corpus_covers_the_five_families_and_more() -> None:
    families = {f for f, *_ in CORPUS}
    assert len(families) == 5 and len(CORPUS) >= 39


def test_the_honest_students_score_exactly_what_they_earn(graded) -> None:
    rows = graded["rows"]
    assert [float(rows["honest-correct"][c]) for c in COLUMNS] == [1.0, 1.0, 1.0]
    assert [float(rows["honest-stubs"][c]) for c in COLUMNS] == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("i", range(len(CORPUS)), ids=[f"{f}: {label}" for f, label, _ in CORPUS])
def test_no_attack_earns_a_mark(graded, i: int) -> None:
    row = graded["rows"][f"attack{i:02d}"]
    assert [float(row[c]) for c in COLUMNS] == [0.0, 0.0, 0.0], (CORPUS[i][1], row)


def test_a_submission_of_links_is_read_as_nothing(graded) -> None:
    row = graded["rows"]["attack-links"]
    assert float(row["total"]) == 0.0
    text = graded["feedback"]["attack-links"]
    assert "(not a plain file)" in text and "missing" in text


def test_nothing_outside_the_graders_outputs_changed(graded) -> None:
    assert graded["after"] == graded["before"]
    assert graded["after_cwd"] == graded["before_cwd"]


def test_nothing_outlives_the_grading(graded) -> None:
    assert graded["csv_now"] == graded["csv_then"] and MARKER not in graded["csv_now"]
    assert _running(MARKER) == []


def test_no_feedback_carries_a_secret_or_a_control_character(graded) -> None:
    for name, text in graded["feedback"].items():
        assert CANARY not in text, name
        assert not re.search(r"[\x00-\x08\x0b-\x1f\x7f]", text), name
    leak = graded["feedback"][
        next(n for n, (_, label) in graded["names"].items() if "feedback" in label)
    ]
    assert "leak:" in leak  # the exception was reported, without what it could not read


def test_the_run_says_how_long_it_took(graded) -> None:
    print(f"\n{len(graded['rows'])} submissions of notebook 02 graded in {graded['seconds']:.0f} s")
    assert "sandbox: bubblewrap" in graded["stdout"]


def test_without_the_sandbox_the_same_attacks_do_see_the_secrets(tmp_path) -> None:
    """The corpus can fail: graded with --unsafe-no-sandbox, the read-only attacks on the
    course and the home folder find them (and the CSV and feedback say it was unsafe)."""
    home = tmp_path / "home"
    home.mkdir()
    env = {**os.environ, "HOME": str(home)}
    run = [sys.executable, "-m", "ekfslam", "lab"]
    release = [*run, "release", "handout", "--notebooks", "02", "--seed", "9"]
    subprocess.run(release, cwd=tmp_path, env=env, check=True, capture_output=True)
    stub = json.loads((tmp_path / "handout" / NOTEBOOK).read_text(encoding="utf-8"))
    chosen = [
        e
        for e in CORPUS
        if e[1] in ("the key's file", "the course folder", "the instructor's home")
    ]
    for i, (_, _, source) in enumerate(chosen):
        source = source.replace("{COURSE}", str(tmp_path / "lab-course"))
        source = source.replace("{HOME}", str(home))
        nb = json.loads(json.dumps(stub))
        _answer_cell(nb)["source"] = source.splitlines(keepends=True)
        (tmp_path / "subs" / f"a{i}").mkdir(parents=True)
        (tmp_path / "subs" / f"a{i}" / NOTEBOOK).write_text(json.dumps(nb), encoding="utf-8")
    grade = [*run, "grade", "subs", "--csv", "g.csv", "--unsafe-no-sandbox", "--timeout", "30"]
    done = subprocess.run(grade, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    rows = list(csv.DictReader((tmp_path / "g.csv").open(encoding="utf-8")))
    assert [float(r["1a"]) for r in rows] == [1.0] * len(chosen)
    assert {r["sandbox"] for r in rows} == {"none (--unsafe-no-sandbox)"}
    feedback = (tmp_path / "g-feedback" / "a0.txt").read_text(encoding="utf-8")
    assert "GRADED WITHOUT A SANDBOX" in feedback


def test_grade_refuses_in_one_line_where_no_sandbox_can_be_made(tmp_path, monkeypatch, capsys):
    from ekfslam.cli.main import main

    monkeypatch.chdir(tmp_path)
    assert main(["lab", "release", "handout", "--notebooks", "02", "--seed", "1"]) == 0
    (tmp_path / "subs" / "a").mkdir(parents=True)
    monkeypatch.setattr(lab_sandbox.shutil, "which", lambda name: None)
    capsys.readouterr()
    assert main(["lab", "grade", "subs", "--csv", "g.csv"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bubblewrap (bwrap) is not installed" in err
    assert "--unsafe-no-sandbox" in err and "apt install bubblewrap" in err
    assert not (tmp_path / "g.csv").exists()
