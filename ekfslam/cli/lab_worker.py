"""One student's grading for ``python -m ekfslam lab grade``, in a process of its own:
``python -m ekfslam.cli.lab_worker STUDENT_FOLDER COURSE RESULT.json TIMEOUT``.

The student's folder is copied into a private copy of the course (its own gradebook, so students
are graded side by side), and nbgrader's ``autograde`` grades each notebook on its own: the check
cells restored from the course's source (a student's edit of one does not count), every cell
executed, the hidden tests run against the key of ``$EKFSLAM_LAB_KEY``. A notebook has
``TIMEOUT`` seconds in all (`DeadlineExecute`); once they are spent every further cell gets a
second, and the notebook scores 0. Each grade cell's score is nbgrader's (an error or output on
stderr is 0; the hidden test's number is the partial credit); the lines it printed become the
student's feedback. The result is written as JSON for the parent.
"""

from __future__ import annotations

import json
import logging
import shutil
import sys
import tempfile
import time
from pathlib import Path

import nbformat
from nbconvert.preprocessors import ClearMetadataPreprocessor
from nbgrader.converters import Autograde
from nbgrader.coursedir import CourseDirectory
from nbgrader.preprocessors import (
    AssignLatePenalties,
    CheckCellMetadata,
    Execute,
    IgnorePattern,
    LimitOutput,
    SaveAutoGrades,
)
from nbgrader.utils import determine_grade
from traitlets import Float

from ekfslam.teaching.exercises import PREDICTIONS
from ekfslam.teaching.make_lab import ASSIGNMENT, nbgrader_config

TIMED_OUT = "CellTimeoutError"


class DeadlineExecute(Execute):
    """nbgrader's Execute with one time limit for the whole notebook, not one per cell."""

    notebook_timeout = Float(300.0).tag(config=True)

    def preprocess(self, nb, resources=None, km=None):  # type: ignore[no-untyped-def]
        deadline = time.monotonic() + self.notebook_timeout
        self.timeout_func = lambda cell: max(deadline - time.monotonic(), 1.0)
        return super().preprocess(nb, resources, km)


def grade(folder: Path, course: Path, timeout: float) -> dict:
    """The student's scores (grade id -> 0..1), the lines each check printed, and each
    notebook's status."""
    student = folder.name
    names = sorted(p.stem for p in (course / "source" / ASSIGNMENT).glob("*.ipynb"))
    result: dict = {"student": student, "scores": {}, "lines": {}, "notebooks": {}}
    with tempfile.TemporaryDirectory(prefix="ekfslam-grade-") as tmp:
        root = Path(tmp)
        shutil.copytree(course / "source", root / "source")
        shutil.copyfile(course / "gradebook.db", root / "gradebook.db")
        submitted = root / "submitted" / student / ASSIGNMENT
        shutil.copytree(folder, submitted)
        for name in names:
            path = submitted / f"{name}.ipynb"
            if not path.is_file():
                result["notebooks"][name] = "missing: its exercises score 0"
                continue
            started = time.monotonic()
            try:
                nbformat.read(path, as_version=4)
            except Exception as error:
                result["notebooks"][name] = f"not a readable notebook ({type(error).__name__})"
                continue
            status = _autograde(root, student, name, timeout)
            graded = root / "autograded" / student / ASSIGNMENT / f"{name}.ipynb"
            if status is None and graded.is_file():
                status = _collect(nbformat.read(graded, as_version=4), result, timeout)
            result["notebooks"][name] = status or f"graded in {time.monotonic() - started:.0f} s"
    return result


def _autograde(root: Path, student: str, notebook: str, timeout: float) -> str | None:
    """nbgrader's autograde of one notebook; None when it ran, else why it could not."""
    config = nbgrader_config(root, database=True)
    config.CourseDirectory.student_id = student
    config.CourseDirectory.notebook_id = notebook
    config.Autograde.autograde_preprocessors = [
        DeadlineExecute,
        IgnorePattern,
        ClearMetadataPreprocessor,
        LimitOutput,
        SaveAutoGrades,
        AssignLatePenalties,
        CheckCellMetadata,
    ]
    config.DeadlineExecute.notebook_timeout = timeout
    config.Execute.interrupt_on_timeout = True
    converter = Autograde(coursedir=CourseDirectory(config=config), config=config)
    converter.log.setLevel(logging.CRITICAL)
    converter.force = True
    started = time.monotonic()
    try:
        converter.start()
    except Exception as error:  # a dead kernel, a broken notebook: the student's, not ours
        if time.monotonic() - started >= timeout:  # a kernel that did not stop when told
            return f"did not finish within {timeout:g} s: its exercises score 0"
        return f"could not be run ({type(error).__name__}): its exercises score 0"
    return None


def _collect(nb, result: dict, timeout: float) -> str | None:
    """Scores and printed lines of the grade cells of an autograded notebook; a status when the
    notebook ran out of time (then each of its exercises scores 0)."""
    hung = any(
        out.get("output_type") == "error" and out.get("ename") == TIMED_OUT
        for cell in nb.cells
        for out in cell.get("outputs", [])
    )
    errors = []
    for i, cell in enumerate(nb.cells):
        meta = cell.metadata.get("nbgrader", {})
        outputs = cell.get("outputs", [])
        if meta.get("grade") and cell.cell_type == "code":
            grade_id = meta["grade_id"]
            score, points = determine_grade(cell)
            result["scores"][grade_id] = 0.0 if hung else round(float(score or 0.0) / points, 4)
            result["lines"][grade_id] = _printed(outputs)
        elif cell.cell_type == "code":
            errors += [
                f"cell {i} raised {o.get('ename')}: {o.get('evalue')}"[:200]
                for o in outputs
                if o.get("output_type") == "error"
            ]
    if hung:
        return f"did not finish within {timeout:g} s: its exercises score 0"
    if errors:
        return "ran, with errors outside the checks: " + "; ".join(errors)
    return None


def _printed(outputs: list) -> list[str]:
    lines = []
    for out in outputs:
        if out.get("output_type") == "stream":
            lines += [line for line in out.get("text", "").splitlines() if line.strip()]
        elif out.get("output_type") == "error":
            lines.append(f"{out.get('ename')}: {out.get('evalue')}"[:300])
    return lines


def main(argv: list[str]) -> int:
    folder, course, out, timeout = Path(argv[0]), Path(argv[1]), Path(argv[2]), float(argv[3])
    result = grade(folder, course, timeout)
    result["predictions_file"] = (folder / PREDICTIONS).is_file()
    out.write_text(json.dumps(result), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
