"""Write the student notebooks from the solution notebooks: ``python -m ekfslam.teaching.make_lab``.

The committed source of a notebook with exercises is its solved version,
``notebooks/solutions/NN-title.ipynb``. The student version ``notebooks/NN-title.ipynb`` is
generated from it and committed too (a student clones the repository and opens it), and a test
holds it to the source (``--check`` does the same from the shell). The solution is the source
because it is the one that runs as it is: an instructor edits and executes one file, and the
markers are plain comments, so there is no third copy to keep in step.

In a code cell of the source, the lines from ``# BEGIN SOLUTION exercise N`` to ``# END SOLUTION``
become ``raise NotImplementedError("exercise N")`` at the marker's indentation. A block that
opens with ``# BEGIN SOLUTION answer`` (a value typed into a cell, checked by `check_answer`)
becomes instead its ``# STUB: ...`` lines, uncommented (``# STUB: x = None`` -> ``x = None``).
The only other change is the path to the seed's runs: the source is one folder deeper.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from ekfslam.errors import InputError

NOTEBOOKS = Path(__file__).resolve().parents[2] / "notebooks"
SOLUTIONS = NOTEBOOKS / "solutions"
BEGIN = re.compile(r"^(\s*)# BEGIN SOLUTION (?:exercise (\w+)|(answer))\s*$")
STUB = re.compile(r"^(\s*)# STUB: (.*)$")
END = re.compile(r"^\s*# END SOLUTION\s*$")
#: (in the source, in the student notebook): notebooks/solutions/ is one folder below notebooks/
RUNS_LINE = (
    'RUNS = Path("..") / ".." / "data" / "runs"  # solutions/ is one folder below notebooks/',
    'RUNS = Path("..") / "data" / "runs"  # Jupyter runs a notebook in its own folder',
)


def strip_solutions(source: str, where: str = "cell") -> str:
    """A code cell's source with every marked solution block replaced by its stub."""
    out: list[str] = []
    block: str | None = None  # the exercise whose block we are in
    stubs: list[str] = []
    for number, line in enumerate(source.split("\n"), start=1):
        begin = BEGIN.match(line)
        if begin and block is not None:
            raise InputError(where, number, f"BEGIN SOLUTION inside the block of {block}")
        if begin:
            indent, exercise, answer = begin.groups()
            block, stubs = (exercise and f"exercise {exercise}") or answer, []
            if exercise:
                out.append(f'{indent}raise NotImplementedError("exercise {exercise}")')
        elif END.match(line):
            if block is None:
                raise InputError(where, number, "END SOLUTION without a BEGIN")
            if block == "answer" and not stubs:
                raise InputError(where, number, "an answer block needs its # STUB: lines")
            out += stubs
            block = None
        elif block is None:
            out.append(line)
        elif stub := STUB.match(line):
            stubs.append(stub.group(1) + stub.group(2))
    if block is not None:
        raise InputError(where, None, f"{block} has no END SOLUTION")
    return "\n".join(out).replace(*RUNS_LINE)


def student_notebook(solution: Path) -> str:
    """The student version of one solution notebook, as the text of an .ipynb file."""
    try:
        nb = json.loads(solution.read_text(encoding="utf-8"))
        cells = nb["cells"]
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise InputError(solution.name, None, f"not a readable notebook ({error})") from None
    for i, cell in enumerate(cells):
        if cell.get("cell_type") == "code":
            text = "".join(cell["source"]) if isinstance(cell["source"], list) else cell["source"]
            stub = strip_solutions(text, f"{solution.name} cell {i}")
            cell["source"] = stub.splitlines(keepends=True)  # as nbformat stores it
    return json.dumps(nb, indent=1, ensure_ascii=False, sort_keys=True) + "\n"


def generated() -> dict[Path, str]:
    """Every student notebook that the solution notebooks make: path -> its text."""
    return {NOTEBOOKS / s.name: student_notebook(s) for s in sorted(SOLUTIONS.glob("*.ipynb"))}


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
