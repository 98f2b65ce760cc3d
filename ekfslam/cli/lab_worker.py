"""One student's grading for ``python -m ekfslam lab grade``: the grader's side, which alone holds
the key. ``python -m ekfslam.cli.lab_worker TASK.pickle RESULT.json`` (a process per student, so
one submission never stops the others), or `grade_task` on a Dask worker.

For each exercise of each notebook, the student's notebook runs in a sandbox of its own
(`ekfslam.cli.lab_sandbox`) up to that exercise's check cell; the exercise's judge
(`ekfslam.teaching.verdicts`) then runs here, on the key's cases, calling the student's function
in the sandbox for each input it needs; the score and every line of feedback are computed here.
A notebook that is missing or unreadable, a function that is not defined, a sandbox that dies,
runs out of time or answers what is not a value: that exercise scores 0, and the feedback says
why. No check cell of the student's notebook decides anything (the sandbox's checks say yes and
judge nothing), and no output of the notebook is read: a silenced cell or a printed "Right!"
earns nothing. Predictions are read from the submitted ``lab-predictions.json`` only and
compared with the outcomes the release recorded from the solutions.
"""

from __future__ import annotations

import ast
import json
import pickle
import re
import sys
import tempfile
import threading
import time
from pathlib import Path

from ekfslam.analysis.lab_key import EXERCISES
from ekfslam.cli.lab_sandbox import Sandbox, SandboxAnswer, SandboxFailed, package_for
from ekfslam.teaching.exercises import PREDICTIONS
from ekfslam.teaching.lab_wire import parse_source
from ekfslam.teaching.make_lab import grader_meta
from ekfslam.teaching.verdicts import JudgeFailed, run_exercise

MAX_FILE = 20 * 2**20  # bytes of one submitted file
MAX_LINE = 300
_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u200b-\u200f\u202a-\u202e\u2066-\u2069]")
#: packages built in this process, per exercise (a Dask worker grades many students)
_PACKAGES: dict[tuple[str, bool], Path] = {}
_PACKAGE_ROOT: list[tempfile.TemporaryDirectory] = []
_BUILDING = threading.Lock()


def clean(text: object, limit: int = MAX_LINE) -> str:
    """`text` on one line, without control characters (a terminal's escape codes)."""
    return _CONTROL.sub("", " ".join(str(text).split()))[:limit]


def packages(numbers: list[str], sandboxed: bool) -> dict[str, Path]:
    """Each exercise's sandbox package, built once per process (by one thread: a Dask worker
    grades students in several)."""
    with _BUILDING:
        return _packages(numbers, sandboxed)


def _packages(numbers: list[str], sandboxed: bool) -> dict[str, Path]:
    if not _PACKAGE_ROOT:
        _PACKAGE_ROOT.append(tempfile.TemporaryDirectory(prefix="ekfslam-lab-packages-"))
    root = Path(_PACKAGE_ROOT[0].name)
    for n in numbers:
        if (n, sandboxed) not in _PACKAGES:
            folder = root / f"{n}-{'sandbox' if sandboxed else 'plain'}"
            _PACKAGES[(n, sandboxed)] = package_for(EXERCISES[n], folder, sandboxed=sandboxed)
    return {n: _PACKAGES[(n, sandboxed)] for n in numbers}


def _student_cells(notebook: dict, released: dict | None) -> list[str]:
    """The sources of the student's own code: the answer cells and any cell not in the
    students' copy as released."""
    known = set()
    if released is not None:
        known = {"".join(c.get("source", [])) for c in released.get("cells", [])}
    own = []
    for cell in notebook.get("cells", []):
        if not isinstance(cell, dict) or cell.get("cell_type") != "code":
            continue
        source = cell.get("source", "")
        source = "".join(source) if isinstance(source, list) else str(source)
        if grader_meta(cell).get("solution") or source not in known:
            own.append(source)
    return own


def derives(sources: list[str]) -> bool:
    """True when the student's own code asks sympy to differentiate (``.jacobian``, ``diff``):
    read from the source here, not reported by the student's process."""
    for source in sources:
        try:
            tree = parse_source(source)
        except SyntaxError:
            continue  # IPython syntax (a magic): no derivation to find in it
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                f = node.func
                name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
                if name in ("jacobian", "diff"):
                    return True
    return False


def grade_predictions(raw: bytes | None, outcomes: dict[str, dict[str, str]]) -> dict:
    """Each prediction's score from the submitted file: the share of its keys whose recorded
    first answer is the outcome."""
    scores, lines = {}, {}
    recorded: dict = {}
    problem = None
    if raw is None:
        problem = f"no {PREDICTIONS} was handed in: predictions score 0"
    else:
        try:
            recorded = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError):
            problem = f"{PREDICTIONS} is not JSON: predictions score 0"
        if not isinstance(recorded, dict):
            recorded, problem = {}, problem or f"{PREDICTIONS} is not a JSON object"
    for grade_id, keys in outcomes.items():
        right = [recorded.get(k) == outcome for k, outcome in keys.items()]
        scores[grade_id] = round(sum(right) / len(right), 4) if right else 0.0
        said = [k for k in keys if isinstance(recorded.get(k), str)]
        lines[grade_id] = (
            [problem]
            if problem
            else [
                f"{k}: recorded {clean(recorded[k], 60)!r}, "
                + ("right" if recorded[k] == keys[k] else "not what happened")
                for k in said
            ]
            or ["no prediction recorded"]
        )
    return {"scores": scores, "lines": lines}


def grade_task(task: dict) -> dict:
    """One student's result: {"student", "scores", "lines", "notebooks"}; `task` holds the
    student's files (name -> bytes), the key's cases, the course's layout and the limits."""
    student, files, course = task["student"], task["files"], task["course"]
    sandboxed, timeout = task["sandboxed"], float(task["timeout"])
    numbers = [n for nb in course["notebooks"].values() for n in nb["exercises"]]
    given = task.get("packages")  # built once by `lab grade` for its local workers
    built = {n: Path(p) for n, p in given.items()} if given else packages(numbers, sandboxed)
    result: dict = {"student": student, "scores": {}, "lines": {}, "notebooks": {}}
    spent: list[float] = []  # CPU seconds of each sandbox, as it reported them
    runs = task.get("runs")
    with tempfile.TemporaryDirectory(prefix="ekfslam-grade-") as tmp:
        for stem, layout in course["notebooks"].items():
            started = time.monotonic()
            name = f"{stem}.ipynb"
            raw = files.get(name)
            if raw is None:
                result["notebooks"][stem] = "missing: its exercises score 0"
                continue
            try:
                notebook = json.loads(raw.decode("utf-8"))
                if not isinstance(notebook, dict) or not isinstance(notebook.get("cells"), list):
                    raise ValueError("no list of cells")
            except (UnicodeDecodeError, ValueError, RecursionError) as error:
                result["notebooks"][stem] = f"not a readable notebook ({clean(error, 80)})"
                continue
            path = Path(tmp) / name
            path.write_bytes(raw)
            own = _student_cells(notebook, layout.get("released"))
            problems = []
            for n in layout["exercises"]:
                score, lines, trouble = _grade_exercise(
                    n, built[n], path, task["cases"][n], own, timeout, sandboxed, runs, spent
                )
                result["scores"][n], result["lines"][n] = score, lines
                problems += trouble
            status = f"graded in {time.monotonic() - started:.0f} s"
            if problems:
                status += "; " + "; ".join(dict.fromkeys(problems))
            result["notebooks"][stem] = clean(status, 600)
    predicted = grade_predictions(files.get(PREDICTIONS), course["predictions"])
    result["scores"] |= predicted["scores"]
    result["lines"] |= predicted["lines"]
    result["lines"] = {k: [clean(line) for line in v] for k, v in result["lines"].items()}
    result["sandbox_cpu"] = round(sum(spent), 2)
    return result


def _grade_exercise(
    n: str,
    package: Path,
    notebook: Path,
    cases: list[dict],
    own: list[str],
    timeout: float,
    sandboxed: bool,
    runs: str | None,
    spent: list[float],
) -> tuple[float, list[str], list[str]]:
    exercise = EXERCISES[n]
    box = None
    try:
        with Sandbox(
            package,
            notebook,
            exercise,
            n,
            timeout,
            sandboxed=sandboxed,
            runs=Path(runs) if runs else None,
        ) as box:
            if not box.defined:
                why = f"Exercise {n}: your notebook does not define {exercise.function} before "
                why += "its check"
                first = f" ({box.errors[-1]})" if box.errors else "."
                return 0.0, [why + first], []
            answer = SandboxAnswer(box, derives(own))
            verdict = run_exercise(exercise, answer, cases)
            said = verdict.line
            if not verdict.done:
                said = f"Exercise {n}: not done yet: {exercise.function} is still the stub."
            line = f"Graded on {verdict.total} cases you have not seen: {said}"
            return round(verdict.score, 4), [line], []
    except JudgeFailed as failed:  # the check's own error: the instructor hears of it
        said = "the grader could not judge your answer (its own error, not yours): your "
        said += "instructor has been told"
        return (
            0.0,
            [f"Exercise {n}: scores 0 for now: {said}."],
            [f"exercise {n}: the judge failed: {clean(str(failed), 120)}"],
        )
    except SandboxFailed as failed:
        if str(failed) == "timeout":
            why = f"did not finish within {timeout:g} s"
        else:
            why = str(failed)
        return 0.0, [f"Exercise {n}: scores 0: {clean(why)}"], [f"exercise {n}: {clean(why, 120)}"]
    finally:
        if box is not None:
            spent.append(box.cpu)


def main(argv: list[str]) -> int:
    task_path, out = Path(argv[0]), Path(argv[1])
    task = pickle.loads(task_path.read_bytes())  # the grader's own file, written for this run
    out.write_text(json.dumps(grade_task(task)), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
