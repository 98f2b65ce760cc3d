"""``python -m ekfslam lab release DIR`` and ``lab grade SUBMISSIONS --csv FILE``: the lab as a
course hands it out and grades it.

``release`` writes the students' copy into DIR (the notebooks 02-07 with their stubs, the runs
they read, a README; no solution, no key) and the course folder (``--course``, default
``lab-course``, relative to where the command runs): the solved notebooks, ``course.json`` (which
exercises and predictions each notebook holds) and the grading key of
`ekfslam.analysis.lab_key`, cases drawn now from a fresh seed. Both are written whole or not at
all: a release that fails leaves neither folder behind.

``grade`` grades SUBMISSIONS, one folder per student holding that student's notebooks (and the
``lab-predictions.json`` their first predictions were recorded in). Every submission is copied
before any is graded; each student is graded in a process of its own (`ekfslam.cli.lab_worker`),
each exercise in a sandbox of its own (`ekfslam.cli.lab_sandbox`: bubblewrap; without it
``grade`` refuses unless told ``--unsafe-no-sandbox``) within ``--timeout`` seconds. A notebook
that is missing, cannot be read, kills its process or runs out of time scores 0 on its
exercises, and the feedback says which and why. One student's submission never stops the
others'. The CSV has one row per student: ``student``, each exercise's score (0 to 1) under its
number, each graded prediction, ``total`` (the sum) and ``sandbox``; beside it a feedback file
per student. ``--jobs N`` grades N students at once on this machine; ``--dask ADDRESS`` on a
Dask cluster's workers (each needs bubblewrap too).
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ekfslam.analysis.lab_key import EXERCISES, read_key, write_key
from ekfslam.analysis.parallel import run_tasks
from ekfslam.cli import args as ca
from ekfslam.cli.lab_sandbox import INSTALL, package_for, seed_runs, unavailable
from ekfslam.cli.lab_worker import MAX_FILE, clean, grade_task
from ekfslam.errors import ConfigError, InputError
from ekfslam.files import atomic_write_text
from ekfslam.places import seed_run
from ekfslam.teaching.exercises import PREDICTIONS
from ekfslam.teaching.make_lab import (
    SOLUTIONS,
    grader_meta,
    read_notebook,
    student_notebook,
    write_notebook,
)

KEY = "key.pkl"
LAYOUT = "course.json"
DEFAULT_COURSE = Path("lab-course")
EXERCISE_TIMEOUT_S = 120.0
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

Install ekfslam from where your instructor says (it is not on PyPI: the course's copy of the
repository, `pip install <that folder>`, or the wheel they hand out), then open the notebooks
with `jupyter lab`. They read the seed's runs from the
package (`ekfslam.places.seed_run`); `data/runs/` here holds the same runs to look at.

**Predictions.** Some cells ask you to predict an outcome before the experiment runs. Your
first answer is recorded in `lab-predictions.json` beside the notebooks and is the one that
counts: run each prediction cell once you have written your guess.

**To hand in:** this folder's notebooks and `lab-predictions.json`, as they are, in one folder.
Do not call the package's own version of an exercise from your function: the check notices it,
and while your notebook is graded the package's version is not there at all (the exercise then
scores 0). Each exercise is graded by running your notebook, on its own, up to that exercise's
check cell: keep what your function needs in the cells above it.
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
        default=EXERCISE_TIMEOUT_S,
        help="seconds one exercise's sandbox may run, its notebook included (default: %(default)g)",
    )
    grade.add_argument(
        "--jobs",
        type=ca.whole(1, 64),
        default=max(1, os.cpu_count() or 1),
        help="students graded at once on this machine (default: the cores, %(default)s)",
    )
    grade.add_argument(
        "--dask",
        metavar="ADDRESS",
        help="grade on this Dask scheduler's workers (tcp://host:8786; each needs bubblewrap)",
    )
    grade.add_argument(
        "--unsafe-no-sandbox",
        action="store_true",
        help="grade without a sandbox where none can be made (the notebooks can then read and "
        "write whatever you can; the CSV and every feedback file say so)",
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
    release, course = args.dir.resolve(), args.course.resolve()
    if release == course or release.is_relative_to(course) or course.is_relative_to(release):
        raise InputError(str(args.dir), None, "the students' copy and the course must be apart")
    for folder in (args.dir, args.course):
        if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
            if not args.overwrite:
                raise InputError(str(folder), None, "is not empty (add --overwrite to replace it)")
    solved = [read_notebook(p) for p in sources]
    staged = []
    try:  # both folders made beside their targets, moved into place once whole
        for target in (release, course):
            target.parent.mkdir(parents=True, exist_ok=True)
            staged.append(Path(tempfile.mkdtemp(prefix=f".{target.name}-", dir=target.parent)))
        students, private = staged
        for path, nb in zip(sources, solved, strict=True):
            (students / path.name).write_text(
                write_notebook(student_notebook(nb, str(path))), "utf-8"
            )
        for name in LAB_RUNS:
            shutil.copytree(seed_run(name), students / "data" / "runs" / name)
        (students / "README.md").write_text(STUDENT_README, encoding="utf-8")
        (private / "source").mkdir()
        for path in sources:
            shutil.copyfile(path, private / "source" / path.name)
        seed = write_key(private / KEY, args.seed, solved)
        layout = course_layout(sources, solved, seed)
        (private / LAYOUT).write_text(json.dumps(layout, indent=1) + "\n", encoding="utf-8")
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(students, 0o777 & ~mask)  # the hand-out, readable as any folder
        os.chmod(private, 0o700)  # the course: the instructor's alone
        for target, made in ((release, students), (course, private)):
            if target.exists():
                shutil.rmtree(target) if target.is_dir() else target.unlink()
            made.rename(target)
    finally:
        for made in staged:
            shutil.rmtree(made, ignore_errors=True)
    print(f"wrote {args.dir}: {len(sources)} notebooks, {len(LAB_RUNS)} runs, README.md")
    print(
        f"wrote {args.course}: the solved notebooks, the course's layout and the grading key "
        f"(seed {seed}); keep it, and keep it from the students"
    )
    return 0


def course_layout(sources: list[Path], solved: list[dict], seed: int) -> dict:
    """What `grade` needs of the course besides the key: each notebook's exercises (by grade
    id, in order) and predictions, and the CSV's columns."""
    notebooks = {}
    for path, nb in zip(sources, solved, strict=True):
        ids = [grader_meta(c).get("grade_id") for c in nb["cells"] if grader_meta(c).get("grade")]
        notebooks[path.stem] = {
            "exercises": [i for i in ids if i in EXERCISES],
            "predictions": [i for i in ids if i not in EXERCISES],
        }
    return {"version": 1, "seed": seed, "notebooks": notebooks}


# --- grade -------------------------------------------------------------------------------------


def cmd_grade(args: argparse.Namespace) -> int:
    course = args.course
    for needed in (course / KEY, course / LAYOUT, course / "source"):
        if not needed.exists():
            raise InputError(str(needed), None, "missing: run `lab release` into this course")
    if not args.submissions.is_dir():
        raise InputError(str(args.submissions), None, "is not a folder of student folders")
    why = unavailable() if not args.unsafe_no_sandbox else None
    if why is not None:
        raise ConfigError(
            f"lab grade: no sandbox to grade in: {why}; {INSTALL}; or add --unsafe-no-sandbox "
            "to grade without one (the notebooks can then read and write whatever you can)"
        )
    sandboxed = not args.unsafe_no_sandbox
    layout = _read_layout(course / LAYOUT)
    key = read_key(course / KEY)
    staged, dropped = stage(args.submissions)  # every submission copied before any is graded
    if not staged:
        raise InputError(str(args.submissions), None, "holds no student folder")
    feedback = args.feedback or args.csv.with_name(args.csv.stem + "-feedback")
    notebooks = _notebooks(course, layout)
    columns = course_columns(notebooks)
    started = time.perf_counter()
    runs = seed_runs()
    built = None if args.dask else tempfile.TemporaryDirectory(prefix="ekfslam-lab-packages-")
    numbers = [n for nb in notebooks.values() for n in nb["exercises"]]
    ready = {
        n: str(package_for(EXERCISES[n], Path(built.name) / n, sandboxed=sandboxed))
        for n in (numbers if built else [])
    }
    tasks = [
        {
            "student": student,
            "files": files,
            "course": {"notebooks": notebooks, "predictions": _outcomes(key, notebooks)},
            "cases": key["cases"],
            "timeout": args.timeout,
            "sandboxed": sandboxed,
            "runs": str(runs) if runs else None,
            "packages": ready,  # empty on Dask: each worker builds its own
        }
        for student, files in staged.items()
    ]
    if args.dask:
        results = run_tasks(grade_task, [(t,) for t in tasks], dask=args.dask)
    else:

        def one(task: dict) -> dict:
            result = grade_in_process(task, args.timeout * len(columns) + 60)
            cpu = result.get("sandbox_cpu", 0.0)
            print(
                f"{task['student']}: total {total(result, columns):.2f} of {len(columns)} "
                f"(its sandboxes: {cpu:.1f} s CPU)"
            )
            return result

        with built, ThreadPoolExecutor(max_workers=args.jobs) as pool:
            results = list(pool.map(one, tasks))
    for result, student in zip(results, staged, strict=True):
        result["student"] = student  # the folder's name, whatever a worker sent back
        result["dropped"] = dropped.get(student, [])
    mode = "bubblewrap" if sandboxed else "none (--unsafe-no-sandbox)"
    write_csv(args.csv, results, columns, mode)
    feedback.mkdir(parents=True, exist_ok=True)
    for result in results:
        atomic_write_text(
            feedback / f"{result['student']}.txt", feedback_text(result, columns, mode)
        )
    print(
        f"graded {len(results)} students in {time.perf_counter() - started:.0f} s "
        f"(sandbox: {mode}): wrote {args.csv} and {len(results)} feedback files in {feedback}"
    )
    skipped = sum(len(v) for v in dropped.values())
    if skipped:
        print(f"left out {skipped} files that are not notebooks or {PREDICTIONS} (see feedback)")
    return 0


def _read_layout(path: Path) -> dict:
    try:
        layout = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        raise InputError(str(path), None, f"not the course's layout ({error})") from None
    if not isinstance(layout, dict) or layout.get("version") != 1:
        raise InputError(str(path), None, "not a course of this ekfslam (run `lab release` again)")
    return layout


def _notebooks(course: Path, layout: dict) -> dict:
    """Each notebook's exercises and predictions, with the students' copy as released (the
    grader tells the student's own cells from it)."""
    out = {}
    for stem, entry in layout["notebooks"].items():
        source = course / "source" / f"{stem}.ipynb"
        released = student_notebook(read_notebook(source), str(source))
        out[stem] = {**entry, "released": released}
    return out


def _outcomes(key: dict, notebooks: dict) -> dict:
    wanted = {p for nb in notebooks.values() for p in nb["predictions"]}
    return {k: v for k, v in key["predictions"].items() if k in wanted}


def stage(submissions: Path) -> tuple[dict[str, dict[str, bytes]], dict[str, list[str]]]:
    """Every student's notebooks and predictions file, read into memory now (a copy no student's
    grading can change); the other entries of each folder, left out by name."""
    staged: dict[str, dict[str, bytes]] = {}
    dropped: dict[str, list[str]] = {}
    for folder in sorted(submissions.iterdir()):
        if folder.name.startswith(".") or folder.is_symlink() or not folder.is_dir():
            continue
        files, left = {}, []
        for entry in sorted(folder.iterdir()):
            wanted = entry.suffix == ".ipynb" or entry.name == PREDICTIONS
            if not wanted:
                left.append(f"{entry.name} (not a notebook)")
            elif entry.is_symlink() or not entry.is_file():
                left.append(f"{entry.name} (not a plain file)")
            elif entry.stat().st_size > MAX_FILE:
                left.append(f"{entry.name} (over {MAX_FILE // 2**20} MiB)")
            else:
                files[entry.name] = entry.read_bytes()
        staged[folder.name] = files
        dropped[folder.name] = left
    return staged, dropped


def grade_in_process(task: dict, limit: float) -> dict:
    """`grade_task(task)` in a process of its own, killed with everything it started when it
    runs past `limit` seconds."""
    with tempfile.TemporaryDirectory(prefix="ekfslam-lab-") as tmp:
        task_file, out = Path(tmp) / "task.pickle", Path(tmp) / "result.json"
        task_file.write_bytes(pickle.dumps(task, protocol=pickle.HIGHEST_PROTOCOL))
        command = [sys.executable, "-m", "ekfslam.cli.lab_worker", str(task_file), str(out)]
        with open(Path(tmp) / "stderr.txt", "wb") as err:
            process = subprocess.Popen(
                command,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=err,
                start_new_session=True,  # its sandboxes too: one signal ends them all
            )
            try:
                process.wait(timeout=limit)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
                return _failed(task["student"], f"grading stopped after {limit:g} s")
        if process.returncode != 0 or not out.exists():
            text = (Path(tmp) / "stderr.txt").read_bytes()[-4000:].decode("utf-8", "replace")
            last = text.strip().splitlines()[-1:] or ["?"]
            return _failed(task["student"], f"the grader failed: {clean(last[0])}")
        return json.loads(out.read_text("utf-8"))


def _failed(student: str, why: str) -> dict:
    return {"student": student, "scores": {}, "lines": {}, "notebooks": {"(all)": why}}


def course_columns(notebooks: dict) -> list[str]:
    """The CSV's score columns: the exercises first (1a, 1b, 2a, ... 9), then the graded
    predictions (predict-02, ...)."""
    ids = [i for nb in notebooks.values() for i in nb["exercises"] + nb["predictions"]]
    return [n for n in EXERCISES if n in ids] + [i for i in ids if i not in EXERCISES]


def total(result: dict, columns: list[str]) -> float:
    return float(sum(result["scores"].get(c, 0.0) for c in columns))


def write_csv(path: Path, results: list[dict], columns: list[str], mode: str) -> None:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["student", *columns, "total", "sandbox"])
    for r in results:
        scores = [f"{r['scores'].get(c, 0.0):.4g}" for c in columns]
        writer.writerow([r["student"], *scores, f"{total(r, columns):.4g}", mode])
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, out.getvalue())


def feedback_text(result: dict, columns: list[str], mode: str) -> str:
    lines = [f"Lab feedback for {result['student']}", ""]
    if not mode.startswith("bubblewrap"):
        lines += ["GRADED WITHOUT A SANDBOX (--unsafe-no-sandbox)", ""]
    lines += [
        f"{name}: {clean(status, 600)}" for name, status in sorted(result["notebooks"].items())
    ]
    lines += [f"left out: {clean(d)}" for d in result.get("dropped", [])]
    lines.append("")
    for column in columns:
        score = result["scores"].get(column, 0.0)
        lines.append(f"{column}: {score:.2f}")
        lines += [f"    {clean(line)}" for line in result["lines"].get(column, [])]
    lines += ["", f"total: {total(result, columns):.2f} of {len(columns)}"]
    return "\n".join(lines) + "\n"
