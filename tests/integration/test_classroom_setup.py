"""Colab and Binder: every notebook's first cell installs ekfslam only when it is not importable,
and the Binder and conda environments list what the package needs."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb")) + sorted(
    (ROOT / "solutions").glob("*.ipynb")
)
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))


def code_cells(path: Path) -> list[str]:
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    return ["".join(c["source"]) for c in cells if c["cell_type"] == "code"]


def setup_cell() -> str:
    return code_cells(NOTEBOOKS[0])[0]


def test_every_notebook_opens_with_the_same_install_cell_then_the_backend() -> None:
    cell = setup_cell()
    assert 'importlib.util.find_spec("ekfslam") is None' in cell
    for path in NOTEBOOKS:
        first, second = code_cells(path)[:2]
        assert first == cell, f"{path.name}: the first code cell is not the install cell"
        assert second.lstrip().startswith("%matplotlib"), path.name
    assert f'REPOSITORY = "{PYPROJECT["project"]["urls"]["Repository"]}"' in cell


def run_cell(monkeypatch, cwd: Path, importable: bool) -> list[list[str]]:
    """Execute the install cell in `cwd`; the commands it would have run."""
    ran: list[list[str]] = []
    monkeypatch.setattr(subprocess, "run", lambda cmd, **kw: ran.append(cmd))
    real = importlib.util.find_spec
    fake = lambda name, *a: real(name, *a) if importable or name != "ekfslam" else None  # noqa: E731
    monkeypatch.setattr(importlib.util, "find_spec", fake)
    monkeypatch.chdir(cwd)
    monkeypatch.setattr("os.chdir", lambda path: None)  # the cell's move into the clone
    exec(compile(setup_cell(), "<install cell>", "exec"), {})
    return ran


def test_the_install_cell_does_nothing_where_ekfslam_imports(monkeypatch) -> None:
    assert run_cell(monkeypatch, ROOT / "notebooks", importable=True) == []


def test_the_install_cell_installs_the_checkout_it_runs_in(monkeypatch, tmp_path: Path) -> None:
    (tmp_path / "pyproject.toml").write_text("")
    (tmp_path / "notebooks" / "solutions").mkdir(parents=True)
    ran = run_cell(monkeypatch, tmp_path / "notebooks" / "solutions", importable=False)
    assert len(ran) == 1, ran
    assert ran[0][1:4] == ["-m", "pip", "install"] and ran[0][-1] == str(tmp_path)


def test_the_install_cell_clones_the_repository_on_colab(monkeypatch, tmp_path: Path) -> None:
    ran = run_cell(monkeypatch, tmp_path, importable=False)
    assert ran[0][:2] == ["git", "clone"] and PYPROJECT["project"]["urls"]["Repository"] in ran[0]
    assert ran[1][-1] == str(tmp_path / "ekfslam")


def _names(requirements: list[str]) -> set[str]:
    return {re.split(r"[<>=\[ ;]", r.strip(), maxsplit=1)[0].lower() for r in requirements}


def test_binder_installs_every_dependency_and_the_package() -> None:
    pytest.importorskip("yaml")
    import yaml

    env = yaml.safe_load((ROOT / "binder" / "environment.yml").read_text(encoding="utf-8"))
    pip = next(d["pip"] for d in env["dependencies"] if isinstance(d, dict))
    assert _names(pip) == _names(PYPROJECT["project"]["dependencies"])
    assert "pip install --no-deps -e ." in (ROOT / "binder" / "postBuild").read_text()


def test_the_conda_environment_lists_what_requirements_txt_does() -> None:
    pytest.importorskip("yaml")
    import yaml

    env = yaml.safe_load((ROOT / "environment.yml").read_text(encoding="utf-8"))
    pip = next(d["pip"] for d in env["dependencies"] if isinstance(d, dict))
    for name in ("requirements.txt", "requirements-test.txt"):
        lines = (ROOT / name).read_text(encoding="utf-8").splitlines()
        wanted = [line for line in lines if line.strip() and not line.startswith("#")]
        # `-e .[test]` installs everything `-e .` does
        listed = {p.removeprefix("-e ") for p in pip}
        assert all(w.removeprefix("-e ") + "[test]" in listed or w in pip for w in wanted), name
