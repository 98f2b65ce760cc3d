"""Write the student notebooks from the solution notebooks: ``python -m ekfslam.teaching.make_lab``.

The committed source of a notebook with exercises is its solved version,
``solutions/NN-title.ipynb`` (beside ``notebooks/``, so that a student's ``jupyter lab notebooks/``
does not show it), in nbgrader's source format (its cell metadata, kept so
that nbgrader's tools still read the notebooks; nbgrader itself is not needed). Its exercise
cells are solution cells, whose ``# BEGIN SOLUTION`` ... ``# END SOLUTION`` region becomes
`STUB` in the students' copy; a value typed into a cell (checked by `check_answer`) or a
prediction is a solution cell too, whose stub line (``x = None``) stands before its region. Each
exercise's check cell is a grade cell (locked, one point, its grade id the exercise's number:
``1a`` ... ``9``, ``predict-02`` ...); a ``### BEGIN HIDDEN TESTS`` part in it is removed from
the students' copy. The lab's grader (``python -m ekfslam lab grade``) does not run check cells:
it scores each exercise's function itself, outside the student's process.

The student version ``notebooks/NN-title.ipynb`` is what `student_notebook` makes of it, committed
too (a student clones the repository and opens it), and a test holds it to the source
(``--check`` does the same from the shell); ``python -m ekfslam lab release`` makes the same.
"""

from __future__ import annotations

import argparse
import copy
import json
import re
import sys
from pathlib import Path

from ekfslam.errors import InputError

NOTEBOOKS = Path(__file__).resolve().parents[2] / "notebooks"
SOLUTIONS = NOTEBOOKS.parent / "solutions"
#: What a solution region becomes in the students' copy: a function that is still the stub
#: returns None (the check says "not done yet"); a typed-in value keeps the None before it.
STUB = "# YOUR CODE HERE"
_BEGIN = re.compile(r"^(\s*)#+\s*BEGIN SOLUTION\b")
_END = re.compile(r"^\s*#+\s*END SOLUTION\b")
_BEGIN_HIDDEN = re.compile(r"^\s*###\s*BEGIN HIDDEN TESTS\b")
_END_HIDDEN = re.compile(r"^\s*###\s*END HIDDEN TESTS\b")


def grader_meta(cell: dict) -> dict:
    """A cell's nbgrader metadata ({} for a cell without)."""
    meta = cell.get("metadata", {})
    found = meta.get("nbgrader", {}) if isinstance(meta, dict) else {}
    return found if isinstance(found, dict) else {}


def _strip(
    lines: list[str], path: str, cell: int, begin: re.Pattern, end: re.Pattern, stub: bool
) -> list[str]:
    out: list[str] = []
    inside = False
    for line in lines:
        opened = begin.match(line)
        if opened and not inside:
            inside = True
            if stub:
                out.append(f"{opened.group(1)}{STUB}\n")
        elif inside and end.match(line):
            inside = False
        elif not inside:
            out.append(line)
    if inside:
        raise InputError(path, None, f"cell {cell}: a region opened and never closed")
    if out:
        out[-1] = out[-1].rstrip("\n")
    return out


def student_notebook(source: dict, path: str = "<notebook>") -> dict:
    """The students' copy of the solved notebook `source`: each solution region `STUB`, each
    hidden test removed, outputs cleared, nbgrader cells undeletable and locked ones read-only."""
    nb = copy.deepcopy(source)
    for i, cell in enumerate(nb.get("cells", [])):
        meta = grader_meta(cell)
        lines = cell.get("source", [])
        lines = lines.splitlines(keepends=True) if isinstance(lines, str) else list(lines)
        if meta.get("solution"):
            lines = _strip(lines, path, i, _BEGIN, _END, stub=True)
        if meta.get("grade"):
            lines = _strip(lines, path, i, _BEGIN_HIDDEN, _END_HIDDEN, stub=False)
        cell["source"] = lines
        if cell.get("cell_type") == "code":
            cell["outputs"], cell["execution_count"] = [], None
        if meta:
            extra = {"deletable": False} | ({"editable": False} if meta.get("locked") else {})
            cell["metadata"] = extra | {k: v for k, v in cell["metadata"].items() if k not in extra}
            cell["metadata"]["nbgrader"] = {"cell_type": cell.get("cell_type")} | meta
    return nb


def write_notebook(nb: dict) -> str:
    """The notebook's text as Jupyter writes it (one-space indent, a newline at the end)."""
    return json.dumps(nb, indent=1, ensure_ascii=False) + "\n"


def read_notebook(path: Path) -> dict:
    try:
        nb = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise InputError(str(path), None, f"not a readable notebook ({error})") from None
    if not isinstance(nb, dict) or not isinstance(nb.get("cells"), list):
        raise InputError(str(path), None, "not a notebook: no list of cells")
    return nb


def generated() -> dict[Path, str]:
    """Every student notebook that the solution notebooks make: path -> its text."""
    return {
        NOTEBOOKS / p.name: write_notebook(student_notebook(read_notebook(p), str(p)))
        for p in sorted(SOLUTIONS.glob("*.ipynb"))
    }


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
