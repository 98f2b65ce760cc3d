"""Write the student notebooks from the solution notebooks with nbgrader's assign step:
``python -m ekfslam.teaching.make_lab``.

The committed source of a notebook with exercises is its solved version,
``notebooks/solutions/NN-title.ipynb``: an nbgrader source notebook. Its exercise cells are
nbgrader solution cells, whose ``# BEGIN SOLUTION`` ... ``# END SOLUTION`` region nbgrader's
``generate_assignment`` replaces by `STUB`; a value typed into a cell (checked by `check_answer`)
or a prediction is a solution cell too, whose stub line (``x = None``) stands before its region.
Each exercise's check cell is an nbgrader grade cell (locked, one point, its grade id the
exercise's number: ``1a`` ... ``9``, ``predict-02`` ...) whose ``### BEGIN HIDDEN TESTS`` part
calls the grader (`ekfslam.analysis.lab_key.grade`) and is removed from the students' copy.

The student version ``notebooks/NN-title.ipynb`` is what nbgrader generates from it, committed
too (a student clones the repository and opens it), and a test holds it to the source
(``--check`` does the same from the shell). `generate_course` runs the same step for
``python -m ekfslam lab release``, with nbgrader's gradebook, which grading needs.
"""

from __future__ import annotations

import argparse
import logging
import shutil
import sys
import tempfile
from pathlib import Path

from nbgrader.converters import GenerateAssignment, NbGraderException
from nbgrader.coursedir import CourseDirectory
from traitlets.config import Config

from ekfslam.errors import InputError

NOTEBOOKS = Path(__file__).resolve().parents[2] / "notebooks"
SOLUTIONS = NOTEBOOKS / "solutions"
#: nbgrader's name of the assignment: the lab, notebooks 02-07
ASSIGNMENT = "lab"
#: What a solution region becomes in the students' copy: a function that is still the stub
#: returns None (the check says "not done yet"); a typed-in value keeps the None before it.
STUB = "# YOUR CODE HERE"


def nbgrader_config(course: Path, *, database: bool) -> Config:
    """nbgrader's settings for the lab in the course folder `course`."""
    config = Config()
    config.CourseDirectory.root = str(course)
    config.CourseDirectory.assignment_id = ASSIGNMENT
    config.CourseDirectory.db_url = f"sqlite:///{course / 'gradebook.db'}"
    config.ClearSolutions.code_stub = {"python": STUB}
    config.GenerateAssignment.no_database = not database
    config.SaveCells.enabled = database
    return config


def generate_course(course: Path, sources: list[Path], *, database: bool = True) -> Path:
    """nbgrader's ``generate_assignment`` on the solution notebooks `sources` in the course
    folder `course` (its ``source/lab/``, its gradebook); returns the students' copy it writes,
    ``course/release/lab/``."""
    source = course / "source" / ASSIGNMENT
    source.mkdir(parents=True, exist_ok=True)
    for path in sources:
        shutil.copyfile(path, source / path.name)
    config = nbgrader_config(course, database=database)
    coursedir = CourseDirectory(config=config)
    converter = GenerateAssignment(coursedir=coursedir, config=config)
    converter.log.setLevel(logging.ERROR)
    converter.force = True
    try:
        converter.start()
    except NbGraderException as error:
        raise InputError(
            str(source), None, f"nbgrader could not generate the lab: {error}"
        ) from None
    return course / "release" / ASSIGNMENT


def generated() -> dict[Path, str]:
    """Every student notebook that the solution notebooks make: path -> its text."""
    sources = sorted(SOLUTIONS.glob("*.ipynb"))
    with tempfile.TemporaryDirectory() as tmp:
        release = generate_course(Path(tmp), sources, database=False)
        return {NOTEBOOKS / p.name: (release / p.name).read_text("utf-8") for p in sources}


def stale() -> list[str]:
    """Names of the student notebooks that differ from what their solutions generate."""
    return [
        path.name
        for path, text in generated().items()
        if not path.exists() or path.read_text(encoding="utf-8") != text
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m ekfslam.teaching.make_lab", description=__doc__
    )
    parser.add_argument("--check", action="store_true", help="only report stale notebooks")
    args = parser.parse_args(argv)
    try:
        if args.check:
            names = stale()
            for name in names:
                print(f"{name} is stale: run python -m ekfslam.teaching.make_lab")
            return 1 if names else 0
        for path, text in generated().items():
            path.write_text(text, encoding="utf-8")
            print(f"wrote {path.relative_to(NOTEBOOKS.parent)}")
    except InputError as error:
        print(f"make_lab: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
