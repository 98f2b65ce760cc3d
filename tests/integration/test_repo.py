"""The repository keeps its promises: lint clean, README commands = CI, the README a front door
(short, its example runs), equations mapped."""

from __future__ import annotations

import contextlib
import importlib
import io
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
README = (REPO / "README.md").read_text(encoding="utf-8")


def _bash_blocks(text: str) -> list[str]:
    return [b.strip() for b in re.findall(r"```bash\n(.*?)```", text, flags=re.S)]


@pytest.mark.parametrize("args", [["check", "."], ["format", "--check", "."]])
def test_ruff_is_clean_on_the_whole_tree(args):
    # this interpreter's ruff, not whatever `ruff` is on PATH (a venv need not be activated)
    out = subprocess.run(
        [sys.executable, "-m", "ruff", *args], cwd=REPO, capture_output=True, text=True
    )
    assert "No module named ruff" not in out.stderr, (
        "ruff is a test dependency: pip install -r requirements-test.txt"
    )
    assert out.returncode == 0, out.stdout + out.stderr


def test_ci_runs_exactly_the_readmes_test_command():
    test_command = next(b for b in _bash_blocks(README) if "pytest" in b)
    ci = (REPO / ".ci" / "run").read_text()
    assert test_command in ci.splitlines(), f"{test_command!r} is not a line of .ci/run"


def test_readme_main_command_replays_a_run_that_exists():
    main = next(b for b in _bash_blocks(README) if "ekfslam run" in b)
    run_dir = re.search(r"ekfslam run (\S+)", main).group(1)
    assert (REPO / run_dir / "run.json").is_file()
    assert main.startswith("python -m pip install -r requirements.txt")


def test_the_readme_is_a_front_door_of_at_most_250_lines():
    lines = README.splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines: move the rest into docs/"


def test_ci_builds_the_book_with_the_readmes_command_before_the_tests():
    book = next(b for b in _bash_blocks(README) if "sphinx" in b)
    assert book == "python -m sphinx -W -b html docs docs/_build/html"
    ci = (REPO / ".ci" / "run").read_text().splitlines()
    assert book in ci, f"{book!r} is not a line of .ci/run"
    test_command = next(b for b in _bash_blocks(README) if "pytest" in b)
    assert ci.index(book) < ci.index(test_command)  # the tests check the book CI built


def test_every_link_of_the_readme_into_the_repository_leads_to_a_file():
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", README)
    local = [link for link in links if "://" not in link]
    assert len(local) >= 20  # the README is a front door: it links into the documentation
    missing = [link for link in local if not (REPO / link).exists()]
    assert not missing, f"README links to files that do not exist: {missing}"


def _python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def _run(code: str, monkeypatch) -> str:
    monkeypatch.chdir(REPO)  # the examples read data/runs/ as a user in a checkout would
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "example", "exec"), {"__name__": "__example__"})
    return out.getvalue()


def test_the_readmes_example_maps_a_log_from_arrays_in_at_most_15_lines(monkeypatch):
    (example,) = _python_blocks(README.split("## Your own robot's log")[1].split("\n## ")[0])
    assert len(example.splitlines()) <= 15
    assert "run_from_arrays" in example and "np.loadtxt" in example
    printed = _run(example, monkeypatch).splitlines()
    # the octagon's eight tags where the filter put them (before eq. 17's alignment)
    assert [line.split(":")[0] for line in printed] == [f"tag {i}" for i in range(8)]
    # ... and says so (regression: it printed +0.867 where the figures put tag 0 at 0.75)
    assert printed[0] == "tag 0: x +0.867 m, y +0.176 m (before alignment)"
    assert all(line.endswith("(before alignment)") for line in printed)
    after = README.split("## Your own robot's log")[1].split("\n## ")[0].split(example)[1]
    assert "before the\nalignment of eq. (17)" in after and "ekfslam.align(" in after


def test_the_guides_arrays_example_scores_its_map(monkeypatch):
    page = (REPO / "docs" / "guide" / "replaying.md").read_text(encoding="utf-8")
    (example,) = _python_blocks(page.split("<!-- tested:")[1])
    printed = _run(example, monkeypatch).strip()
    match = re.fullmatch(r"8 landmarks, map error (\d\.\d{3}) m \(eq\. 17\)", printed)
    assert match, printed
    assert 0.003 <= float(match[1]) <= 0.008  # the square's Table 1 row: about 5 mm


def test_every_equation_reference_in_the_docs_names_real_code():
    page = (REPO / "docs" / "equations.md").read_text(encoding="utf-8")
    table = page.split("| eq. |")[1]
    names = re.findall(r"`(ekfslam\.[\w.]+)`", table)
    assert len(names) >= 12
    for dotted in names:
        parts = dotted.split(".")
        for split in range(len(parts), 1, -1):
            try:
                obj = importlib.import_module(".".join(parts[:split]))
            except ModuleNotFoundError:
                continue
            for attr in parts[split:]:
                obj = getattr(obj, attr)
            break
        else:
            pytest.fail(f"{dotted} is not importable")


def test_environment_yml_installs_the_same_set_as_pip():
    env = (REPO / "environment.yml").read_text()
    assert "python=3.11" in env and "-e .[test]" in env
    assert "." in (REPO / "requirements.txt").read_text().splitlines()  # a copy: clean_save
    assert "-e .[test]" in (REPO / "requirements-test.txt").read_text()


#: the formatter's skip marker is kept only for a table whose alignment carries meaning (issue 24)
MAX_FMT_SKIPS = 10
_FMT_SKIP = "# fmt" + ": skip"  # spelled in two so this file does not count itself


def test_the_formatter_decides_the_layout():
    """At most MAX_FMT_SKIPS skip markers of the formatter in the repository, each saying why.

    Modules are split along concepts, never to meet a line count: there is no line rule, and the
    formatter's layout is not overridden to keep a module short (issue 24).
    """
    found = []
    for p in sorted(REPO.rglob("*.py")):
        if any(part.startswith(".") or part in {"build", "_build"} for part in p.parts):
            continue
        for number, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1):
            if _FMT_SKIP in line:
                found.append((p.relative_to(REPO).as_posix(), number, line))
    assert len(found) <= MAX_FMT_SKIPS, f"{len(found)} skip markers (at most {MAX_FMT_SKIPS})"
    for name, number, line in found:
        why = line.split(_FMT_SKIP, 1)[1].strip()
        assert why.startswith(("-", ":")) and len(why) > 10, (
            f"{name}:{number}: a skip marker says why its alignment matters"
        )


def test_the_package_wraps_angles_in_one_place():
    """One angle wrap (`ekfslam.geometry.wrap_angle`, issue 24): a modulo by 2π written again
    elsewhere is a second copy (plausibility's bearing check held one)."""
    modulo = re.compile(r"%\s*\(?\s*(2\s*\*\s*(math|np)\.pi|TWO_PI|math\.tau|np\.tau)")
    copies = [
        f"{path.relative_to(REPO)}:{number}"
        for path in sorted((REPO / "ekfslam").rglob("*.py"))
        if path.name != "geometry.py" and "__pycache__" not in path.parts
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if modulo.search(line)
    ]
    assert copies == [], copies
