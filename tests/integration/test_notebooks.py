"""The classroom notebooks: stored clean, executed without error, importing only public API.

Every ``notebooks/*.ipynb`` and ``solutions/*.ipynb`` is picked up automatically: the
student version of a lab notebook and its solved source are both executed, and their exercise
checks must say "not done yet" (every stub) and "right" (every solution). Each is executed in
memory (nothing is written back) in a fresh kernel whose working directory is the notebook's own
folder, as Jupyter would run it, with ``MPLBACKEND=Agg`` so that a notebook without a
``%matplotlib`` line never opens a window.
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

NOTEBOOK_DIR = Path(__file__).resolve().parents[2] / "notebooks"
SOLUTION_DIR = NOTEBOOK_DIR.parent / "solutions"
NOTEBOOKS = sorted(NOTEBOOK_DIR.glob("*.ipynb")) + sorted(SOLUTION_DIR.glob("*.ipynb"))
KERNEL_TIMEOUT_S = 300


def _name(path: Path) -> str:
    # NN-... and solutions/NN-...: the ids the shared-data selection names (test_shared_data)
    return path.name if path.parent == NOTEBOOK_DIR else f"{path.parent.name}/{path.name}"


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
            offenders[_name(path)] = cells
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
    assert private_ekfslam_names("from ekfslam.core.filter.ekf import EKFSLAM, _wrap") == [
        "ekfslam.core.filter.ekf._wrap"
    ]
    assert private_ekfslam_names("import ekfslam\nekfslam.core.filter.ekf._wrap(1.0)") == [
        "ekfslam.core.filter.ekf._wrap"
    ]
    assert private_ekfslam_names("from ekfslam._internal import x") == ["ekfslam._internal"]
    assert private_ekfslam_names("%matplotlib inline\nfrom ekfslam import replay\nx._y") == []


@pytest.mark.parametrize("path", NOTEBOOKS, ids=_name)
def test_notebook_imports_only_public_api(path: Path) -> None:
    nb = nbformat.read(path, as_version=4)
    private = {i: private_ekfslam_names(c.source) for i, c in enumerate(nb.cells)}
    private = {
        i: names for i, names in private.items() if names and nb.cells[i].cell_type == "code"
    }
    assert not private, f"{path.name} uses private ekfslam names (cell: names): {private}"


def test_first_code_cell_after_the_install_cell_sets_the_backend() -> None:
    """The install cell (test_classroom_setup.py) comes first, then the backend."""
    wrong = []
    for path in NOTEBOOKS:
        cells = _code_cells(nbformat.read(path, as_version=4))[1:]
        if not cells or not cells[0].source.lstrip().startswith("%matplotlib"):
            wrong.append(_name(path))
    assert not wrong, f"the second code cell must start with %matplotlib inline/widget: {wrong}"


# --- execution ----------------------------------------------------------------------------------

STOP = (
    "NotebookStop"  # ekfslam.teaching.lessons.NotebookStop: the data a notebook needs is not here
)


def _reads_shared_data(path: Path) -> bool:
    return "mrclam_dataset(" in path.read_text(encoding="utf-8")


def _executable(path: Path):
    marks = [pytest.mark.slow] + ([pytest.mark.shared_data] if _reads_shared_data(path) else [])
    return pytest.param(path, marks=marks, id=_name(path))


def execute_notebook(path: Path) -> tuple[object, float]:
    """Run a notebook in memory in a fresh kernel (nothing is written back); (notebook, s)."""
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(
        nb,
        timeout=KERNEL_TIMEOUT_S,
        kernel_name="python3",
        allow_errors=True,  # collect every error, then fail with all of them
        resources={"metadata": {"path": str(path.parent)}},
    )
    started = time.perf_counter()
    client.execute()
    return nb, time.perf_counter() - started


def stopped_at(nb) -> tuple[int, str] | None:
    """(cell, message) of the first cell that stopped the notebook (`NotebookStop`), or None.

    Jupyter's *Run All* runs nothing after it; nbclient (allow_errors) runs on, so the errors
    of later cells are not the notebook's.
    """
    for i, cell in enumerate(nb.cells):
        for out in cell.get("outputs", []) if cell.cell_type == "code" else []:
            if out.get("output_type") == "error" and out.get("ename") == STOP:
                return i, out.get("evalue", "")
    return None


def judge_execution(name: str, nb, seconds: float, data_missing) -> None:
    """Fail on any error before a stop; a stop (missing data) skips, or fails in CI."""
    stop = stopped_at(nb)
    if stop is not None:
        nb = nbformat.from_dict(nb)  # a copy: only the cells Run All would have run
        nb.cells = nb.cells[: stop[0]]
    errors = notebook_errors(nb)
    assert not errors, f"{name} ({seconds:.1f} s) has errors:\n" + "\n".join(errors)
    if stop is not None:
        data_missing(f"{name} stopped at cell {stop[0]}: {stop[1]}")


@pytest.mark.parametrize("path", [_executable(p) for p in NOTEBOOKS])
def test_notebook_executes(path: Path, monkeypatch, record_property, data_missing) -> None:
    monkeypatch.setenv("MPLBACKEND", "Agg")  # the kernel inherits it
    nb, seconds = execute_notebook(path)
    record_property("runtime_s", round(seconds, 1))
    print(f"\n{_name(path)}: executed in {seconds:.1f} s")
    judge_execution(_name(path), nb, seconds, data_missing)
    judge_exercises(path, nb)


def _stdout_lines(nb) -> list[str]:
    lines = []
    for cell in _code_cells(nb):
        for out in cell.get("outputs", []):
            if out.get("output_type") == "stream" and out.get("name") == "stdout":
                lines += out["text"].splitlines()
    return lines


def exercise_verdicts(nb) -> list[str]:
    """The lines the exercise checks printed ("Exercise 1a: ..."), in order."""
    return [line for line in _stdout_lines(nb) if line.startswith("Exercise ")]


def judge_exercises(path: Path, nb) -> None:
    """A solution notebook passes every check; its student version is "not done yet" in each."""
    solved = path.parent == SOLUTION_DIR
    source = SOLUTION_DIR / path.name
    if not source.exists():
        return
    exercises = re.findall(r"# BEGIN SOLUTION exercise (\w+)", source.read_text(encoding="utf-8"))
    verdicts = exercise_verdicts(nb)
    if solved:  # the values typed in (check_answer) are answered too
        assert not [v for v in _stdout_lines(nb) if v.startswith("Not ")], _stdout_lines(nb)
    assert [v.split(":")[0] for v in verdicts] == [f"Exercise {n}" for n in exercises], verdicts
    expected = "right on every test case" if solved else "not done yet"
    assert all(expected in v for v in verdicts), verdicts


def test_notebooks_reach_mrclam_only_through_the_stopping_helper() -> None:
    """find_dataset raises on missing data and the next cells cascade into NameErrors;
    teaching.mrclam_dataset stops the notebook in one line instead."""
    direct = [
        path.name
        for path in NOTEBOOKS
        for cell in _code_cells(nbformat.read(path, as_version=4))
        if re.search(r"\bfind_dataset\(", cell.source)
    ]
    assert not direct, f"use ekfslam.teaching.lessons.mrclam_dataset in: {direct}"
    assert [p.name for p in NOTEBOOKS if _reads_shared_data(p)] == [
        "09-trust-the-ellipses.ipynb",
        "10-real-robots.ipynb",
        "13-five-robots-one-map.ipynb",
    ]


@pytest.mark.slow
def test_a_notebook_without_its_data_stops_in_one_line_and_skips(
    monkeypatch, tmp_path: Path, data_missing
) -> None:
    """No shared data and nothing fetched: notebook 10 shows one line that says how to fetch
    the data, Run All goes no further, and its test skips with that reason (fails in CI)."""
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("EKFSLAM_SHARED_DATA", str(tmp_path / "no-shared-data"))
    monkeypatch.setenv("EKFSLAM_CACHE", str(tmp_path / "empty-cache"))
    monkeypatch.delenv("CI", raising=False)
    path = NOTEBOOK_DIR / "10-real-robots.ipynb"
    nb, seconds = execute_notebook(path)
    cell, message = stopped_at(nb)
    # the cell that asks for the data (after the install cell), not a later one
    assert "mrclam_dataset(" in nb.cells[cell].source, nb.cells[cell].source
    assert "python -m ekfslam fetch mrclam 7" in message
    (error,) = [o for o in nb.cells[cell].outputs if o.output_type == "error"]
    assert error.traceback == [message]  # one line, no traceback
    with pytest.raises(pytest.skip.Exception, match="fetch mrclam 7"):
        judge_execution(path.name, nb, seconds, data_missing)
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match="CI must have it"):
        judge_execution(path.name, nb, seconds, data_missing)


@pytest.mark.slow
def test_a_notebook_copied_out_of_the_repository_finds_its_data(monkeypatch, tmp_path) -> None:
    """The notebooks read the seed's runs through the package (`ekfslam.places.seed_run`), not
    a path beside them: copied anywhere (a lab release, Colab), a notebook runs."""
    monkeypatch.setenv("MPLBACKEND", "Agg")
    copy = tmp_path / "elsewhere" / "02-robot-and-arena.ipynb"
    copy.parent.mkdir()
    copy.write_bytes((NOTEBOOK_DIR / copy.name).read_bytes())
    nb, _ = execute_notebook(copy)
    assert notebook_errors(nb) == []
    assert [v.split(":")[0] for v in exercise_verdicts(nb)] == ["Exercise 1a", "Exercise 1b"]
