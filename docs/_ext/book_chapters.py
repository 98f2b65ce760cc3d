"""The notebooks as the book's chapters: the worked chapter, not the students' hand-out.

A notebook with exercises has two versions: the solved one (``solutions/``, the source, beside
``notebooks/``) and the students' (``notebooks/``, its stubs). Its page in the book is made from
the solved one, executed, so a reader sees the chapter finished. On every notebook page
(`chapter`):

- the first cell, the Colab/Binder install cell, is left out: the page's launch buttons (Binder,
  Colab) do that job;
- an exercise's task (the text under a heading ``Exercise ...``) is shown as a callout, and its
  worked answer (a solution cell) folded under it, without the lab's markers
  (``# BEGIN SOLUTION`` ...) and without the stub line a typed-in answer replaces;
- a check cell's hidden tests (the grader's, ``### BEGIN HIDDEN TESTS``) are left out;
- a notebook without a solved version (08-13) keeps a cell's worked answer in the cell's
  metadata (``"ekfslam": {"book": "consistent_q = (0.02, 0.02)"}``), shown in its place;
- notebook 08's live panel (widgets, which need a kernel) is shown as a still picture of its
  figure, under a note that says how to run it live.

The notebooks' kernels run with ``EKFSLAM_BOOK=1`` (conf.py): a prediction left open in a
notebook without a solved version is answered by the experiment instead of "Not answered yet",
and nothing is recorded beside the notebook (``ekfslam.teaching.exercises.check_prediction``).
"""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

from ekfslam.teaching import make_lab

#: the first line of the notebooks' shared first cell (tests/integration/test_classroom_setup.py)
INSTALL_CELL = "# Colab and Binder:"
EXERCISE = re.compile(r"^(#{2,4}) (Exercises?\b.*)$")
HEADING = re.compile(r"^#{1,6} ")
MARKER = re.compile(r"^\s*#+\s*(BEGIN|END) SOLUTION\b")
ASSIGNED = re.compile(r"^\s*([A-Za-z_]\w*)\s*=")
#: under the title of a notebook whose figures are widgets (ipympl): the book shows them still
LIVE = (
    "```{note}\nOn this page the panel and its figures are still: the book runs no kernel. "
    "Run the notebook in JupyterLab (`jupyter lab notebooks/`) or as a web app "
    "(`voila notebooks/08-live-tuning.ipynb`) to move the sliders; the launch buttons above "
    "open it on Binder.\n```"
)
#: the call that makes notebook 08's panel, and what the book shows in its place
PANEL = "tuning_panel("
STILL = (
    "import io as _io\n\nfrom IPython.display import Image as _Image\n\n"
    "_png = _io.BytesIO()\npanel.tuner.figure.savefig(_png, format='png', dpi=100)\n"
    "_Image(_png.getvalue())"
)
STUB_LINE = re.compile(r"^\s*([A-Za-z_]\w*)\s*=\s*None\b")


def _lines(cell: dict) -> list[str]:
    source = cell.get("source", [])
    return source.splitlines(keepends=True) if isinstance(source, str) else list(source)


def callouts(markdown: str) -> str:
    """`markdown` with the text under each exercise heading in a callout (the heading kept, so
    that links to it hold); the callout ends at the next heading or the end of the cell."""
    out: list[str] = []
    inside = False
    for line in markdown.splitlines():
        if inside and HEADING.match(line):
            out += [":::", ""]
            inside = False
        if inside and not line.strip() and out[-1] == "":
            continue  # the heading's blank line: the callout's own is there
        out.append(line)
        if EXERCISE.match(line):
            out += ["", ":::{admonition} The exercise", ":class: tip exercise", ""]
            inside = True
    if inside:
        out.append(":::")
    return "\n".join(out)


def worked_answer(lines: list[str]) -> list[str]:
    """A solution cell as the book shows it: the markers gone, and gone too the stub lines
    (``x = None``) of the names the solution assigns."""
    solved, inside = set(), False
    for line in lines:
        if MARKER.match(line):
            inside = MARKER.match(line).group(1) == "BEGIN"
        elif inside and ASSIGNED.match(line):
            solved.add(ASSIGNED.match(line).group(1))
    kept = []
    for line in lines:
        if MARKER.match(line):
            continue
        stub = STUB_LINE.match(line)
        if stub and stub.group(1) in solved:
            continue
        kept.append(line)
    if kept:
        kept[-1] = kept[-1].rstrip("\n")
    return kept


def chapter(nb: dict, path: str = "<notebook>") -> dict:
    """The notebook `nb` as the book's chapter (see the module's docstring)."""
    nb = copy.deepcopy(nb)
    cells = []
    for i, cell in enumerate(nb.get("cells", [])):
        lines = _lines(cell)
        meta = make_lab.grader_meta(cell)
        if cell.get("cell_type") == "code" and "".join(lines).startswith(INSTALL_CELL):
            continue
        if cell.get("cell_type") == "markdown":
            lines = callouts("".join(lines)).splitlines(keepends=True)
        if meta.get("solution"):
            lines = worked_answer(lines)
            tags = cell.setdefault("metadata", {}).setdefault("tags", [])
            tags.append("hide-input")
        if meta.get("grade"):
            lines = make_lab._strip(
                lines, path, i, make_lab._BEGIN_HIDDEN, make_lab._END_HIDDEN, stub=False
            )
        worked = cell.get("metadata", {}).get("ekfslam", {}).get("book")
        if worked is not None:  # a notebook without a solved version keeps its answer here
            lines = worked.splitlines(keepends=True)
            cell["metadata"].setdefault("tags", []).append("hide-input")
        cell["source"] = lines
        cells.append(cell)
        if cell.get("cell_type") == "code" and PANEL in "".join(lines):
            # the panel is widgets, which the book cannot run: its figure as a still picture
            cell.setdefault("metadata", {}).setdefault("tags", []).append("remove-output")
            cells.append(
                {
                    "cell_type": "code",
                    "id": "book-panel-still",
                    "execution_count": None,
                    "metadata": {"tags": ["remove-input"]},
                    "outputs": [],
                    "source": STILL,
                }
            )
    if any(
        _lines(c)[:1] == ["%matplotlib widget\n"] for c in cells if c.get("cell_type") == "code"
    ):
        cells.insert(
            1, {"cell_type": "markdown", "id": "book-live", "metadata": {}, "source": LIVE}
        )
    nb["cells"] = cells
    return nb


def solved_source(notebooks: Path, docname: str) -> Path | None:
    """The solved version of the notebook page `docname` (``notebooks/NN-title``), if it has one."""
    if not docname.startswith("notebooks/"):
        return None
    solved = notebooks.parent / "solutions" / f"{docname.removeprefix('notebooks/')}.ipynb"
    return solved if solved.is_file() else None


def as_chapter(app, docname: str, source: list[str]) -> None:
    if not docname.startswith("notebooks/") or not str(app.env.doc2path(docname)).endswith(
        ".ipynb"
    ):
        return
    notebooks = Path(app.config.ekfslam_notebooks)
    solved = solved_source(notebooks, docname)
    text = solved.read_text(encoding="utf-8") if solved else source[0]
    source[0] = json.dumps(chapter(json.loads(text), str(solved or docname)))


def setup(app):
    # before book_notebooks' mark_unexecuted (500), which adds its warning to what this makes
    app.connect("source-read", as_chapter, priority=400)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
