"""``python -m ekfslam lab release DIR`` and ``lab grade SUBMISSIONS --csv FILE``: the lab as a
course hands it out and grades it, on nbgrader.

``release`` runs nbgrader's ``generate_assignment`` on the solution notebooks 02-07 in a course
folder (``--course``, default ``lab-course``: the source notebooks with their hidden tests,
nbgrader's gradebook, and the grading key of `ekfslam.analysis.lab_key`, cases drawn now from a
fresh seed) and copies the students' copy into DIR: the notebooks with their stubs, the runs they
read (also installed with the package, where the notebooks find them) and a README. No solution,
no hidden test, no key.

``grade`` grades SUBMISSIONS, one folder per student holding that student's notebooks (and the
``lab-predictions.json`` their first predictions were recorded in). Each student is graded in a
process of its own, each notebook by nbgrader's ``autograde`` (its check cells restored from the
course, its hidden tests run) within ``--timeout`` seconds; a notebook that is missing, cannot be
read, kills its kernel or runs out of time scores 0 on its exercises, and the feedback says which
and why. One student's submission never stops the others'. The CSV has one row per student:
``student``, each exercise's score (0 to 1) under its number, each graded prediction, ``total``
(the sum); beside it a feedback file per student.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ekfslam.analysis.lab_key import EXERCISES, KEY_ENV, write_key
from ekfslam.cli import args as ca
from ekfslam.errors import InputError
from ekfslam.places import seed_run
from ekfslam.teaching.make_lab import ASSIGNMENT, SOLUTIONS, generate_course

KEY = "key.pkl"
DEFAULT_COURSE = Path("lab-course")
NOTEBOOK_TIMEOUT_S = 300.0
#: the runs the lab's notebooks read (copied into the release beside them)
LAB_RUNS = (
    "square-2laps",
    "octagon-2laps",
    "octagon-2laps-7hz",
    "square-2laps-realistic",
    "octagon-2laps-realistic",
)

STUDENT_README = """# The EKF-SLAM lab

Notebooks 02 to 07: exercises 1a to 9, each a function you write where a cell says
`# YOUR CODE HERE`, and a check cell below it that prints what is right or wrong. Until your
function passes, the cells below use the package's version, so every notebook runs to its end.

Install ekfslam (your instructor says from where; `pip install ekfslam` or the course's
repository), then open the notebooks with `jupyter lab`. They read the seed's runs from the
package (`ekfslam.places.seed_run`); `data/runs/` here holds the same runs to look at.

**Predictions.** Some cells ask you to predict an outcome before the experiment runs. Your
first answer is recorded in `lab-predictions.json` beside the notebooks and is the one that
counts: run each prediction cell once you have written your guess.

**To hand in:** this folder's notebooks and `lab-predictions.json`, as they are, in one folder.
Do not call the package's own version of an exercise from your function: the check notices it
and the exercise then scores 0.
"""


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``lab`` (`help` is the one line of `ekfslam.cli.main.COMMANDS`)."""
    lab = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[0])
    sub = lab.add_subparsers(dest="lab_command", required=True, parser_class=ca.Parser)
    release = sub.add_parser(
        "release",
        help="write the students' copy of the lab (and the course folder that grades it)",
    )
    release.add_argument("dir", type=ca.output_folder, help="the students' copy, a new folder")
    _add_course(release)
    release.add_argument(
        "--seed", type=ca.seed(), help="the seed of the graded cases (default: a random one)"
    )
    release.add_argument(
        "--notebooks",
        nargs="+",
        metavar="NN",
        help="release only these notebooks, by number (say 02 05; default: 02 to 07)",
    )
    release.add_argument("--overwrite", action="store_true", help="replace DIR and the course")
    release.set_defaults(func=cmd_release)
    grade = sub.add_parser("grade", help="grade a folder of submissions, one folder per student")
    grade.add_argument("submissions", type=ca.input_path, help="one folder per student")
    grade.add_argument("--csv", type=ca.output_file([".csv"]), required=True, help="the grades")
    _add_course(grade)
    grade.add_argument(
        "--feedback",
        type=ca.output_folder,
        help="a feedback file per student (default: FILE's name without .csv, plus -feedback)",
    )
    grade.add_argument(
        "--timeout",
        type=ca.positive(),
        default=NOTEBOOK_TIMEOUT_S,
        help="seconds a notebook may run (default: %(default)g)",
    )
    grade.add_argument(
        "--jobs",
        type=ca.whole(1, 64),
        default=max(1, os.cpu_count() or 1),
        help="students graded at once (default: the cores, %(default)s)",
    )
    grade.set_defaults(func=cmd_grade)


def _add_course(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--course",
        type=ca.output_folder,
        default=DEFAULT_COURSE,
        help="the instructor's course folder: sources, hidden tests, key (default: %(default)s)",
    )


# --- release -----------------------------------------------------------------------------------


def cmd_release(args: argparse.Namespace) -> int:
    sources = sorted(SOLUTIONS.glob("*.ipynb"))
    if not sources:
        raise InputError(
            str(SOLUTIONS), None, "no solution notebooks: release from a checkout of the lab"
        )
    if args.notebooks:
        known = {p.name[:2]: p for p in sources}
        unknown = sorted(set(args.notebooks) - set(known))
        if unknown:
            raise InputError(
                "--notebooks",
                None,
                f"no lab notebook {', '.join(unknown)} (known: {', '.join(known)})",
            )
        sources = [known[n] for n in sorted(set(args.notebooks))]
    for folder in (args.dir, args.course):
        if folder.exists() and any(folder.iterdir()):
            if not args.overwrite:
                raise InputError(str(folder), None, "is not empty (add --overwrite to replace it)")
            shutil.rmtree(folder)
    if args.dir.resolve().is_relative_to(args.course.resolve()):
        raise InputError(str(args.dir), None, "the students' copy may not lie in the course")
    args.course.mkdir(parents=True, exist_ok=True)
    release = generate_course(args.course, sources)
    seed = write_key(args.course / KEY, args.seed)
    args.dir.mkdir(parents=True, exist_ok=True)
    notebooks = sorted(release.glob("*.ipynb"))
    for path in notebooks:
        shutil.copyfile(path, args.dir / path.name)
    for name in LAB_RUNS:
        shutil.copytree(seed_run(name), args.dir / "data" / "runs" / name)
    (args.dir / "README.md").write_text(STUDENT_README, encoding="utf-8")
    print(f"wrote {args.dir}: {len(notebooks)} notebooks, {len(LAB_RUNS)} runs, README.md")
    print(
        f"wrote {args.course}: the source notebooks with their hidden tests, the gradebook and "
        f"the grading key (seed {seed}); keep it, and keep it from the students"
    )
    return 0


# --- grade -------------------------------------------------------------------------------------


def cmd_grade(args: argparse.Namespace) -> int:
    course = args.course
    for needed in (course / KEY, course / "gradebook.db", course / "source" / ASSIGNMENT):
        if not needed.exists():
            raise InputError(str(needed), None, "missing: run `lab release` into this course")
    if not args.submissions.is_dir():
        raise InputError(str(args.submissions), None, "is not a folder of student folders")
    students = sorted(
        p for p in args.submissions.iterdir() if p.is_dir() and not p.name.startswith(".")
    )
    if not students:
        raise InputError(str(args.submissions), None, "holds no student folder")
    feedback = args.feedback or args.csv.with_name(args.csv.stem + "-feedback")
    feedback.mkdir(parents=True, exist_ok=True)
    notebooks = sorted((course / "source" / ASSIGNMENT).glob("*.ipynb"))
    columns = course_columns(notebooks)
    started = time.perf_counter()

    def one(folder: Path) -> dict:
        result = grade_student(folder, course, args.timeout, len(notebooks))
        print(f"{folder.name}: total {total(result, columns):.2f} of {len(columns)}", flush=True)
        return result

    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(one, students))
    write_csv(args.csv, results, columns)
    for result in results:
        text = feedback_text(result, columns)
        (feedback / f"{result['student']}.txt").write_text(text, "utf-8")
    print(
        f"graded {len(results)} students in {time.perf_counter() - started:.0f} s: wrote "
        f"{args.csv} and {len(results)} feedback files in {feedback}"
    )
    return 0


def grade_student(folder: Path, course: Path, timeout: float, notebooks: int) -> dict:
    """One student's grades, from a process of its own (killed, with its kernels, when it runs
    past every notebook's time limit and a minute more)."""
    with tempfile.TemporaryDirectory(prefix="ekfslam-lab-") as tmp:
        out = Path(tmp) / "result.json"
        command = [
            sys.executable,
            "-m",
            "ekfslam.cli.lab_worker",
            str(folder.resolve()),
            str(course.resolve()),
            str(out),
            str(timeout),
        ]
        env = {**os.environ, KEY_ENV: str((course / KEY).resolve()), "MPLBACKEND": "Agg"}
        process = subprocess.Popen(
            command,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            start_new_session=True,  # its kernels too: one signal ends them all
        )
        try:
            _, err = process.communicate(timeout=timeout * notebooks + 60)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
            return _failed(folder.name, f"grading stopped after {timeout * notebooks + 60:g} s")
        if process.returncode != 0 or not out.exists():
            last = (err or b"").decode("utf-8", "replace").strip().splitlines()[-1:] or ["?"]
            return _failed(folder.name, f"the grader failed: {last[0]}")
        return json.loads(out.read_text("utf-8"))


def _failed(student: str, why: str) -> dict:
    return {"student": student, "scores": {}, "lines": {}, "notebooks": {"(all)": why}}


def course_columns(notebooks: list[Path]) -> list[str]:
    """The CSV's score columns: the grade ids of the course's check cells, the exercises first
    (1a, 1b, 2a, ... 9), then the graded predictions (predict-02, ...)."""
    ids = []
    for path in notebooks:
        for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
            meta = cell.get("metadata", {}).get("nbgrader", {})
            if meta.get("grade"):
                ids.append(meta["grade_id"])
    return [n for n in EXERCISES if n in ids] + [i for i in ids if i not in EXERCISES]


def total(result: dict, columns: list[str]) -> float:
    return float(sum(result["scores"].get(c, 0.0) for c in columns))


def write_csv(path: Path, results: list[dict], columns: list[str]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(["student", *columns, "total"])
        for r in results:
            scores = [f"{r['scores'].get(c, 0.0):.4g}" for c in columns]
            writer.writerow([r["student"], *scores, f"{total(r, columns):.4g}"])


def feedback_text(result: dict, columns: list[str]) -> str:
    lines = [f"Lab feedback for {result['student']}", ""]
    lines += [f"{name}: {status}" for name, status in sorted(result["notebooks"].items())]
    lines.append("")
    for column in columns:
        score = result["scores"].get(column, 0.0)
        lines.append(f"{column}: {score:.2f}")
        lines += [f"    {line}" for line in result["lines"].get(column, [])]
    lines += ["", f"total: {total(result, columns):.2f} of {len(columns)}"]
    return "\n".join(lines) + "\n"
