"""Every install command the documentation gives works from this repository.

ekfslam is not on PyPI: ``pip install ekfslam`` finds nothing (or someone else's package). Each
``pip install`` line of the README, the book's pages, the instructor's guide, the hand-out's
README and the environment files is read here; a bare ``ekfslam`` is refused, a requirements
file must exist, a local path (``-e .``, ``'.[instructor]'``) must resolve with pip itself
(``pip install --dry-run --no-deps``, which builds the metadata and checks the extra exists),
and a package named from PyPI must be one the project declares (so the name is the one it
uses).
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = [
    ROOT / "README.md",
    ROOT / "notebooks" / "INSTRUCTOR.md",
    ROOT / "data" / "README.md",
    ROOT / "binder" / "postBuild",
    ROOT / "docker" / "grader" / "Containerfile",
    ROOT / "ekfslam" / "cli" / "lab.py",  # the hand-out README it writes
    *sorted((ROOT / "docs").rglob("*.md")),
]
PIP = re.compile(r"pip install ([^`\n;&|)]*)")
#: words of a pip line that are options, not what is installed
OPTIONS_WITH_VALUE = {"-r", "--requirement", "-c", "--constraint", "--prefix", "--target"}


def documented() -> list[tuple[str, str]]:
    """(where, the arguments of one ``pip install``) for every documented install command."""
    found = []
    for path in DOCUMENTS:
        if not path.is_file() or "_build" in path.parts:
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            for match in PIP.finditer(line):
                arguments = match.group(1).split(" #")[0].strip()  # a shell comment after it
                found.append((f"{path.relative_to(ROOT)}:{number}", arguments))
    return found


def declared() -> set[str]:
    """The names of every package pyproject.toml depends on, in any extra."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    specs = list(project["dependencies"])
    for extra in project["optional-dependencies"].values():
        specs += extra
    return {re.split(r"[<>=!~\[ ;]", s, maxsplit=1)[0].lower() for s in specs}


def targets(arguments: str) -> tuple[list[str], list[str]]:
    """(requirements files, what is installed) of one ``pip install``'s arguments."""
    try:
        words = shlex.split(arguments)
    except ValueError:
        words = arguments.split()
    files, things, after, placeholder = [], [], None, False
    for word in words:
        if placeholder or word.startswith("<"):  # "pip install <that folder>": the text says
            placeholder = not word.endswith(">")
            continue
        if after:
            if after in {"-r", "--requirement"}:
                files.append(word)
            after = None
        elif word in OPTIONS_WITH_VALUE:
            after = word
        elif word.startswith("-"):
            continue
        else:
            things.append(word)
    return files, things


def is_local(thing: str) -> bool:
    return thing.startswith((".", "/", "$")) or thing.startswith("'.")


def test_there_are_install_commands_to_check() -> None:
    commands = documented()
    assert len(commands) >= 8
    assert any("-r requirements.txt" in args for _, args in commands)


def test_no_document_says_pip_install_ekfslam() -> None:
    bare = [
        where
        for where, args in documented()
        for thing in targets(args)[1]
        if re.fullmatch(r"ekfslam(\[[\w,-]+\])?([<>=!~].*)?", thing)
    ]
    assert bare == [], f"ekfslam is not on PyPI; these say pip install ekfslam: {bare}"
    assert targets("ekfslam[instructor]")[1] == ["ekfslam[instructor]"]  # what it would catch


def test_every_requirements_file_named_exists() -> None:
    missing = [
        f"{where}: {name}"
        for where, args in documented()
        for name in targets(args)[0]
        if not (ROOT / name).is_file()
    ]
    assert missing == []


def test_every_package_named_from_pypi_is_one_the_project_declares() -> None:
    known = declared()
    unknown = []
    for where, args in documented():
        for thing in targets(args)[1]:
            if is_local(thing) or thing.startswith(("git+", "http")):
                continue
            name = re.split(r"[<>=!~\[ ;]", thing, maxsplit=1)[0].lower()
            if name != "ekfslam" and name not in known:
                unknown.append(f"{where}: {thing}")
    assert unknown == []


@pytest.mark.slow
def test_every_local_install_resolves_with_pip() -> None:
    """``pip install --dry-run --no-deps`` of each distinct local target, from the checkout."""
    local = sorted(
        {
            thing.strip("'\"").replace("/opt/ekfslam", ".")
            for _, args in documented()
            for thing in targets(args)[1]
            if is_local(thing)
        }
    )
    assert "." in local and any("[instructor]" in t for t in local)
    failed = {}
    pip = [sys.executable, "-m", "pip", "install", "--dry-run", "--no-deps", "--quiet"]
    for thing in local:
        done = subprocess.run(
            [*pip, "--no-build-isolation", thing],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=300,
        )
        warned = "does not provide the extra" in done.stderr
        if done.returncode or warned:
            failed[thing] = (done.stderr or done.stdout).strip()[-400:]
    assert failed == {}


def test_a_students_install_pulls_in_no_grading_tool() -> None:
    """The students' command (``pip install -r requirements.txt``: the package, no extra) and
    Binder's list hold no grader: nbgrader's menus and server warnings were every student's."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    graders = ("nbgrader", "otter-grader", "dask")
    students = " ".join(project["dependencies"]).lower()
    students += (ROOT / "binder" / "environment.yml").read_text(encoding="utf-8").lower()
    assert [g for g in graders if g in students] == []
    lines = (ROOT / "requirements.txt").read_text(encoding="utf-8").splitlines()
    assert [line for line in lines if not line.startswith("#")] == ["."]  # the package alone
    assert "ekfslam[dask]" in project["optional-dependencies"]["instructor"]


def test_the_students_notebook_command_opens_a_folder_without_solutions() -> None:
    """Regression: ``jupyter lab notebooks/`` showed ``notebooks/solutions/`` in the students'
    file browser. The solved notebooks are ``solutions/``, beside it."""
    docs = [ROOT / "README.md", ROOT / "notebooks" / "INSTRUCTOR.md", ROOT / "docs" / "index.md"]
    docs.append(ROOT / "docs" / "notebooks.md")
    folders = {
        folder
        for path in docs
        for folder in re.findall(r"jupyter lab (\S+?)/?[`\s]", path.read_text(encoding="utf-8"))
    }
    assert folders == {"notebooks"}, folders
    student = ROOT / "notebooks"
    assert not (student / "solutions").exists()
    solved = [
        p.relative_to(ROOT)
        for p in student.rglob("*.ipynb")
        if "BEGIN SOLUTION" in p.read_text(encoding="utf-8")
    ]
    assert solved == []
    assert len(list((ROOT / "solutions").glob("*.ipynb"))) >= 6
