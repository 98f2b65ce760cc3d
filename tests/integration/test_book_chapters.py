"""A notebook's page in the book is its worked chapter (docs/_ext/book_chapters.py): made from
the solved notebook, without the install cell, each exercise's task a callout, each worked
answer folded and free of the lab's markers, the grader's hidden tests left out."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

import ekfslam.teaching.exercises as exercises

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = ROOT / "notebooks"
sys.path.insert(0, str(ROOT / "docs" / "_ext"))
pytest.importorskip("sphinx", reason="the book's tools: pip install -r requirements-test.txt")

import book_chapters  # noqa: E402  (docs/_ext, after sphinx is known to be here)


def _text(nb: dict, kind: str | None = None) -> str:
    return "\n".join(
        "".join(c["source"]) for c in nb["cells"] if kind is None or c["cell_type"] == kind
    )


@pytest.mark.parametrize("path", sorted((ROOT / "solutions").glob("*.ipynb")), ids=str)
def test_a_lab_notebooks_page_is_its_worked_chapter(path: Path) -> None:
    docname = f"notebooks/{path.stem}"
    assert book_chapters.solved_source(NOTEBOOKS, docname) == path
    source = json.loads(path.read_text(encoding="utf-8"))
    page = book_chapters.chapter(source, str(path))
    text = _text(page)
    assert book_chapters.INSTALL_CELL in _text(source)  # the solved notebook has it ...
    assert book_chapters.INSTALL_CELL not in text  # ... the page does not
    for noise in ("BEGIN SOLUTION", "END SOLUTION", "BEGIN HIDDEN TESTS", "YOUR CODE HERE"):
        assert noise not in text, noise
    markdown = _text(page, "markdown")
    tasks = sum(
        1 for line in _text(source, "markdown").splitlines() if book_chapters.EXERCISE.match(line)
    )
    assert tasks >= 1 and markdown.count(":::{admonition} The exercise") == tasks
    answers = [c for c in page["cells"] if "hide-input" in c["metadata"].get("tags", [])]
    assert len(answers) == sum(
        1 for c in source["cells"] if c["metadata"].get("nbgrader", {}).get("solution")
    )


def test_a_worked_answer_keeps_the_solution_and_drops_the_stub_line() -> None:
    cell = [
        'prediction = None  # "larger" or "smaller"\n',
        "# BEGIN SOLUTION answer\n",
        'prediction = "larger"\n',
        "# END SOLUTION\n",
    ]
    assert book_chapters.worked_answer(cell) == ['prediction = "larger"']
    code = ["def f(x):\n", "    # BEGIN SOLUTION\n", "    return x\n", "    # END SOLUTION\n"]
    assert book_chapters.worked_answer(code) == ["def f(x):\n", "    return x"]


def test_an_exercise_heading_keeps_its_anchor_and_its_task_becomes_a_callout() -> None:
    page = book_chapters.callouts("## Exercise 9 · Eq. (17)\n\nWrite `align`.\n\n## Next\n\nOn.")
    assert page.splitlines()[0] == "## Exercise 9 · Eq. (17)"
    assert ":::{admonition} The exercise\n:class: tip exercise\n\nWrite `align`.\n\n:::" in page
    assert page.endswith("`.\n\n:::\n\n## Next\n\nOn.")


def test_notebook_08s_page_shows_its_panel_still_and_says_how_to_run_it_live() -> None:
    source = json.loads((NOTEBOOKS / "08-live-tuning.ipynb").read_text(encoding="utf-8"))
    page = book_chapters.chapter(source)
    assert "voila notebooks/08-live-tuning.ipynb" in "".join(page["cells"][1]["source"])
    (panel,) = [c for c in page["cells"] if book_chapters.PANEL in "".join(c["source"])]
    still = page["cells"][page["cells"].index(panel) + 1]
    assert "remove-output" in panel["metadata"]["tags"]
    assert still["metadata"]["tags"] == ["remove-input"] and "savefig" in still["source"]
    assert "consistent_q = (0.02, 0.02)" in _text(page)  # its worked answer, from the metadata
    assert "consistent_q = None" in _text(source)  # the students' copy keeps the open one


def test_in_the_book_an_open_answer_is_answered_and_nothing_is_recorded(
    monkeypatch, tmp_path, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv(exercises.BOOK, "1")
    assert exercises.check_answer(None, 3)
    assert exercises.check_prediction(None, "larger", ["larger", "smaller"], "Why.", key="k")
    assert (
        exercises.check_prediction("smaller", "larger", ["larger", "smaller"], "W.", key="k")
        is False
    )
    said = capsys.readouterr().out
    assert "The answer: 3." in said and "The experiment: larger. Why." in said
    assert "Not answered yet" not in said
    assert not (tmp_path / exercises.PREDICTIONS).exists()  # the build writes nothing beside it
    monkeypatch.setenv(exercises.BOOK, "")
    assert exercises.check_answer(None, 3) is False
    assert "Not answered yet" in capsys.readouterr().out
