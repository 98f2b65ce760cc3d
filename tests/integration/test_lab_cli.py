"""``python -m ekfslam lab release`` and ``lab grade`` end to end, as CI runs them: a release of
notebooks 02 and 05, then five generated submissions graded into a CSV, each exercise in its
sandbox: all correct, all stubs, a mix of right and wrong answers, one whose notebooks crash (an
unreadable file, a process that exits) and one that hangs (a short time limit) or is missing a
notebook."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from ekfslam.cli.main import main
from ekfslam.teaching.make_lab import SOLUTIONS

pytestmark = pytest.mark.slow

RIGHT_PREDICTIONS = {"02-wheels": "front-right and rear-left"}
COLUMNS = ["1a", "1b", "6a", "6b", "7", "predict-02"]


def with_answer(notebook: Path, grade_id: str, source: str) -> dict:
    """The students' copy of `notebook`, with the cell of `grade_id` replaced by `source`."""
    nb = json.loads(notebook.read_text(encoding="utf-8"))
    (cell,) = [
        c for c in nb["cells"] if c["metadata"].get("nbgrader", {}).get("grade_id") == grade_id
    ]
    cell["source"] = source.splitlines(keepends=True)
    return nb


def write(nb: dict, path: Path) -> None:
    path.write_text(json.dumps(nb), encoding="utf-8")


def solution_cell(name: str, grade_id: str) -> str:
    nb = json.loads((SOLUTIONS / name).read_text(encoding="utf-8"))
    (cell,) = [
        c for c in nb["cells"] if c["metadata"].get("nbgrader", {}).get("grade_id") == grade_id
    ]
    return "".join(cell["source"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory) -> tuple[dict[str, dict[str, str]], Path, list[str]]:
    tmp = tmp_path_factory.mktemp("lab")
    release, course = tmp / "release", tmp / "course"
    argv = ["lab", "release", str(release), "--course", str(course), "--notebooks", "02", "05"]
    assert main([*argv, "--seed", "11"]) == 0
    nb02, nb05 = release / "02-robot-and-arena.ipynb", release / "05-correction.ipynb"
    subs = tmp / "submissions"
    correct = subs / "correct"
    correct.mkdir(parents=True)
    for name in (nb02.name, nb05.name):
        shutil.copyfile(SOLUTIONS / name, correct / name)
    (correct / "lab-predictions.json").write_text(json.dumps(RIGHT_PREDICTIONS))
    stubs = subs / "stubs"
    stubs.mkdir()
    for path in (nb02, nb05):
        shutil.copyfile(path, stubs / path.name)
    # right 1b, wrong 1a (vy's row negated) and prediction; the seed's (I - KH)Σ for 6a, whose
    # update then still passes 6b (the optimal gain); 7 left a stub
    mixed = subs / "mixed"
    mixed.mkdir()
    right_1a = solution_cell(nb02.name, "answer-1a")
    nb = with_answer(nb02, "answer-1a", right_1a.replace("-w1 + w2 + w3 - w4", "w1 - w2 - w3 + w4"))
    right_1b = solution_cell(nb02.name, "answer-1b")
    nb["cells"] = [
        {**c, "source": right_1b.splitlines(keepends=True)}
        if c["metadata"].get("nbgrader", {}).get("grade_id") == "answer-1b"
        else c
        for c in nb["cells"]
    ]
    write(nb, mixed / nb02.name)
    six = solution_cell(nb05.name, "answer-6a-6b")
    write(
        with_answer(nb05, "answer-6a-6b", six.replace("@ I_KH.T + K @ Q @ K.T", "")),
        mixed / nb05.name,
    )
    (mixed / "lab-predictions.json").write_text(json.dumps({"02-wheels": "both left wheels"}))
    crash = subs / "crash"
    crash.mkdir()
    (crash / nb02.name).write_text("{not a notebook")
    write(with_answer(nb05, "answer-6a-6b", "import os\n\nos._exit(1)\n"), crash / nb05.name)
    hang = subs / "hang"
    hang.mkdir()
    loop = "def twist_from_wheels(wheels, geometry):\n    while True:\n        pass\n"
    write(with_answer(nb02, "answer-1a", loop), hang / nb02.name)  # and no notebook 05
    out = tmp / "grades.csv"
    argv = ["lab", "grade", str(subs), "--csv", str(out), "--course", str(course)]
    assert main([*argv, "--timeout", "30", "--jobs", "2"]) == 0
    with out.open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    header = next(csv.reader(out.open(encoding="utf-8")))
    return {r["student"]: r for r in rows}, tmp / "grades-feedback", header


def scores(row: dict[str, str]) -> list[float]:
    return [float(row[c]) for c in COLUMNS]


def test_the_csv_has_a_row_per_student_and_a_column_per_exercise(graded) -> None:
    rows, _, header = graded
    assert header == ["student", *COLUMNS, "total", "sandbox"]
    assert {r["sandbox"] for r in rows.values()} == {"bubblewrap"}
    assert sorted(rows) == ["correct", "crash", "hang", "mixed", "stubs"]
    for row in rows.values():
        assert abs(float(row["total"]) - sum(scores(row))) < 1e-3


def test_the_correct_submission_scores_full_marks_and_the_stubs_nothing(graded) -> None:
    rows, _, _ = graded
    assert scores(rows["correct"]) == [1.0] * len(COLUMNS)
    assert scores(rows["stubs"]) == [0.0] * len(COLUMNS)


def test_the_mixed_submission_scores_each_exercise_on_its_own(graded) -> None:
    rows, feedback, _ = graded
    got = dict(zip(COLUMNS, scores(rows["mixed"]), strict=True))
    # the short form is right where the gain happens to be the optimal one: partial credit
    assert got["6a"] < 0.5
    del got["6a"]
    assert got == {"1a": 0.0, "1b": 1.0, "6b": 1.0, "7": 0.0, "predict-02": 0.0}
    text = (feedback / "mixed.txt").read_text(encoding="utf-8")
    assert "vy has the wrong sign" in text and "seed's (I - KH)Σ" in text


def test_crashing_hanging_and_missing_notebooks_score_zero_and_are_named(graded) -> None:
    rows, feedback, _ = graded
    assert scores(rows["crash"]) == [0.0] * len(COLUMNS)
    assert scores(rows["hang"]) == [0.0] * len(COLUMNS)
    crash = (feedback / "crash.txt").read_text(encoding="utf-8")
    assert "02-robot-and-arena: not a readable notebook" in crash
    assert (
        "05-correction: graded in" in crash and "exercise 6a: the notebook's process ended" in crash
    )
    hang = (feedback / "hang.txt").read_text(encoding="utf-8")
    assert "exercise 1a: did not finish within 30 s" in hang
    assert "05-correction: missing" in hang


def test_the_release_holds_no_solution_no_hidden_test_and_no_key(graded, tmp_path) -> None:
    release = next(iter(graded[1].parent.glob("release")))
    names = sorted(p.name for p in release.iterdir())
    assert names == ["02-robot-and-arena.ipynb", "05-correction.ipynb", "README.md", "data"]
    for path in release.glob("*.ipynb"):
        text = path.read_text(encoding="utf-8")
        assert "BEGIN SOLUTION" not in text and "HIDDEN TESTS" not in text
    assert (release / "data" / "runs" / "square-2laps" / "run.json").is_file()
    assert not list(release.rglob("*.pkl")) and not list(release.rglob("course.json"))


def test_grade_refuses_a_folder_that_is_no_course_in_one_line(tmp_path, capsys) -> None:
    (tmp_path / "subs" / "a").mkdir(parents=True)
    argv = ["lab", "grade", str(tmp_path / "subs"), "--csv", str(tmp_path / "g.csv")]
    assert main([*argv, "--course", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "run `lab release` into this course" in err
