"""The classroom notebooks: stored clean, executed without error, importing only public API.

Every ``notebooks/*.ipynb`` is picked up automatically. Each is executed in memory (nothing is
written back) in a fresh kernel whose working directory is ``notebooks/``, as Jupyter would run
it, with ``MPLBACKEND=Agg`` so that a notebook without a ``%matplotlib`` line never opens a window.
A notebook fails on any error output: in a cell, in an Output widget (where errors inside widget
callbacks end up) or a "Traceback" on stderr. Run times are printed (``pytest -s``) and
recorded as the test's ``runtime_s`` property; ``--durations=0`` lists them under xdist too.
"""

from __future__ import annotations

import ast
import re
import time
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

NOTEBOOK_DIR = Path(__file__).resolve().parents[1] / "notebooks"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb"))
KERNEL_TIMEOUT_S = 300


def _code_cells(nb) -> list:
    return [cell for cell in nb.cells if cell.cell_type == "code"]


def _dirty_cells(nb) -> list[int]:
    """Indices of code cells that carry outputs or an execution count."""
    return [
        i
        for i, cell in enumerate(nb.cells)
        if cell.cell_type == "code" and (cell.get("outputs") or cell.get("execution_count"))
    ]


def test_notebooks_exist() -> None:
    assert len(NOTEBOOKS) >= 7, f"expected the classroom notebooks 01-07 in {NOTEBOOK_DIR}"


def test_notebooks_are_stored_without_outputs() -> None:
    offenders = {}
    for path in NOTEBOOKS:
        nb = nbformat.read(path, as_version=4)
        cells = _dirty_cells(nb)
        if cells:
            offenders[path.name] = cells
    assert not offenders, f"notebooks stored with outputs or execution counts (cells): {offenders}"


# --- the error detector, tested on its own -----------------------------------------------------


def _errors_in(outputs: list) -> list[str]:
    """Messages of error outputs, and of stderr streams that hold a traceback."""
    found = []
    for out in outputs:
        kind = out.get("output_type")
        if kind == "error":
            found.append(f"{out.get('ename')}: {out.get('evalue')}")
        elif (
            kind == "stream" and out.get("name") == "stderr" and "Traceback" in out.get("text", "")
        ):
            found.append(out["text"].strip().splitlines()[-1])
    return found


def _widget_outputs(state: object) -> list:
    """Every output recorded inside widget state (an Output widget's ``outputs``), recursively."""
    found = []
    if isinstance(state, dict):
        if isinstance(state.get("outputs"), list):
            found += [o for o in state["outputs"] if isinstance(o, dict)]
        for value in state.values():
            found += _widget_outputs(value)
    elif isinstance(state, list):
        for value in state:
            found += _widget_outputs(value)
    return found


def notebook_errors(nb) -> list[str]:
    """All errors in an executed notebook: cell outputs and outputs captured by widgets."""
    errors = []
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code":
            errors += [f"cell {i}: {e}" for e in _errors_in(cell.get("outputs", []))]
    widgets = nb.metadata.get("widgets", {})
    errors += [f"widget output: {e}" for e in _errors_in(_widget_outputs(widgets))]
    return errors


def test_error_detector_sees_cell_stderr_and_widget_errors() -> None:
    nb = nbformat.v4.new_notebook()
    ok = nbformat.v4.new_code_cell("1")
    ok.outputs = [nbformat.v4.new_output("stream", name="stderr", text="a warning\n")]
    bad = nbformat.v4.new_code_cell("1/0")
    bad.outputs = [nbformat.v4.new_output("error", ename="ZeroDivisionError", evalue="division")]
    noisy = nbformat.v4.new_code_cell("")
    noisy.outputs = [
        nbformat.v4.new_output("stream", name="stderr", text="Traceback (most recent)\nKeyError: 3")
    ]
    nb.cells = [ok, bad, noisy]
    callback_error = {"output_type": "error", "ename": "ValueError", "evalue": "in a callback"}
    nb.metadata["widgets"] = {
        "application/vnd.jupyter.widget-state+json": {
            "state": {"abc": {"state": {"outputs": [callback_error]}}}
        }
    }
    assert notebook_errors(nb) == [
        "cell 1: ZeroDivisionError: division",
        "cell 2: KeyError: 3",
        "widget output: ValueError: in a callback",
    ]
    nb.cells, nb.metadata["widgets"] = [ok], {}
    assert notebook_errors(nb) == []


# --- public API only ----------------------------------------------------------------------------

_PRIVATE_ATTRIBUTE = re.compile(r"\bekfslam(?:\.\w+)*\._\w+")


def private_ekfslam_names(source: str) -> list[str]:
    """Underscore names a piece of notebook code takes from ekfslam (imports and attributes)."""
    lines = [line for line in source.splitlines() if not line.lstrip().startswith(("%", "!"))]
    code = "\n".join(lines)
    found = [m.group(0) for m in _PRIVATE_ATTRIBUTE.finditer(code)]
    try:
        tree = ast.parse(code)
    except SyntaxError:
        return found
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("ekfslam"):
            parts = node.module.split(".")
            found += [f"{node.module}" for p in parts if p.startswith("_")]
            found += [f"{node.module}.{a.name}" for a in node.names if a.name.startswith("_")]
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("ekfslam") and any(
                    p.startswith("_") for p in a.name.split(".")
                ):
                    found.append(a.name)
    return sorted(set(found))


def test_private_name_detector() -> None:
    assert private_ekfslam_names("from ekfslam.filter import EKFSLAM, _wrap") == [
        "ekfslam.filter._wrap"
    ]
    assert private_ekfslam_names("import ekfslam\nekfslam.filter._wrap(1.0)") == [
        "ekfslam.filter._wrap"
    ]
    assert private_ekfslam_names("from ekfslam._internal import x") == ["ekfslam._internal"]
    assert private_ekfslam_names("%matplotlib inline\nfrom ekfslam import replay\nx._y") == []


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_imports_only_public_api(path: Path) -> None:
    nb = nbformat.read(path, as_version=4)
    private = {i: private_ekfslam_names(c.source) for i, c in enumerate(nb.cells)}
    private = {
        i: names for i, names in private.items() if names and nb.cells[i].cell_type == "code"
    }
    assert not private, f"{path.name} uses private ekfslam names (cell: names): {private}"


def test_first_code_cell_sets_the_backend() -> None:
    wrong = []
    for path in NOTEBOOKS:
        cells = _code_cells(nbformat.read(path, as_version=4))
        if not cells or not cells[0].source.lstrip().startswith("%matplotlib"):
            wrong.append(path.name)
    assert not wrong, f"first code cell must start with %matplotlib inline/widget: {wrong}"


# --- execution ----------------------------------------------------------------------------------


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_executes(path: Path, monkeypatch, record_property) -> None:
    monkeypatch.setenv("MPLBACKEND", "Agg")  # the kernel inherits it
    nb = nbformat.read(path, as_version=4)  # an in-memory copy: nothing is written back
    client = nbclient.NotebookClient(
        nb,
        timeout=KERNEL_TIMEOUT_S,
        kernel_name="python3",
        allow_errors=True,  # collect every error, then fail with all of them
        resources={"metadata": {"path": str(NOTEBOOK_DIR)}},
    )
    started = time.perf_counter()
    client.execute()
    seconds = time.perf_counter() - started
    record_property("runtime_s", round(seconds, 1))
    print(f"\n{path.name}: executed in {seconds:.1f} s")
    errors = notebook_errors(nb)
    assert not errors, f"{path.name} ({seconds:.1f} s) has errors:\n" + "\n".join(errors)
