"""The import rules of ARCHITECTURE.md, checked over the source with `ast` (no import is executed).

Each subpackage of ekfslam is a floor; a module may import its own floor and the floors listed
for it in `MAY_IMPORT`. On top of that: outside `ekfslam.core.filter` the lower floors never load
the filter at run time, matplotlib belongs to viz and ui, nothing imports inside a function except
an optional heavy dependency with a ``# lazy: why`` comment, `ekfslam/__init__.py` imports nothing
at run time, and the modules form no cycle (counting imports inside functions and module names
in importlib tables). The repository's ``studies/`` and ``benchmarks/`` sit beside the package:
they may import anything in it, never each other, and nothing in it imports them.

A rule broken on purpose is listed in `KNOWN_VIOLATIONS` with its reason (today: none). A
violation not in it fails, and so does an entry that no longer happens.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest
from setuptools import find_packages

REPO = Path(__file__).resolve().parents[1]

# the floor of each top-level name under the package
FLOOR_OF = {
    "errors": "leaves",
    "checks": "leaves",
    "fieldtypes": "leaves",
    "geometry": "leaves",
    "files": "leaves",
    "plausibility": "leaves",
    "places": "leaves",
    "core": "core",
    "teaching": "teaching",
    "logs": "logs",
    "sim": "sim",
    "vision": "vision",
    "pipeline": "pipeline",
    "team": "pipeline",  # a team's logs joined to the joint filter, as pipeline's replay
    "schedule": "pipeline",  # a run as the filter takes it, and the loops that feed it
    "strategies": "pipeline",  # how a replay decides each sighting: known or hidden ids
    "analysis": "analysis",
    "viz": "viz",
    "ui": "ui",
    "cli": "cli",
    "__main__": "main",
    "__init__": "facade",
}
_BELOW_ANALYSIS = {"leaves", "core", "teaching", "logs", "sim", "vision", "pipeline"}
MAY_IMPORT = {  # besides its own floor
    "leaves": {"leaves"},
    "core": {"leaves"},
    "teaching": {"leaves", "core", "logs"},  # a lesson opens its data (and stops without it)
    "logs": {"leaves", "core"},
    "sim": {"leaves", "core", "logs"},  # the simulator writes a run log
    "vision": {"leaves", "core", "logs"},  # frames_run renders and detects a run log's frames
    "pipeline": {"leaves", "core", "logs"},
    "analysis": _BELOW_ANALYSIS,
    "viz": {"leaves", "core", "logs"},  # at run time; types from below ui under TYPE_CHECKING
    "ui": _BELOW_ANALYSIS | {"analysis", "viz"},
    "cli": _BELOW_ANALYSIS | {"analysis", "viz", "ui"},
    "main": {"cli"},
    "facade": set(FLOOR_OF.values()),  # under TYPE_CHECKING only: see the facade rule
}
VIZ_TYPES_FROM = _BELOW_ANALYSIS - {"teaching"} | {"analysis"}
NO_FILTER_FLOORS = {"core", "logs", "sim", "vision", "teaching"}  # core: outside core.filter
# the filter proper (numba): its config and history are plain data anyone below may use
FILTER_MODULES = ("core.filter.ekf", "core.filter.state", "core.filter.compile")
MATPLOTLIB_FLOORS = {"viz", "ui"}
# optional or heavy dependencies a function may import late, with a `# lazy: why` comment
LAZY_OK = {
    "IPython",  # the lab sandbox's notebook shell, in that process only
    "cv2",
    "playwright",
    "rosbags",
    "ipywidgets",
    "matplotlib",
    "pupil_apriltags",
    "distributed",  # the optional extra ekfslam[dask], only for `--dask`
    "imageio_ffmpeg",  # the optional extra ekfslam[video]: its ffmpeg, only for an MP4
}

# The repository's folders beside the package (ARCHITECTURE.md): each may import the package and
# itself, never the other; the package never imports either.
OUTSIDE = ("studies", "benchmarks")

# Rules the code breaks on purpose, each with its reason (violation -> why). Empty: the refactor
# of issue 14 removed every violation it found. A new entry needs a reason a reviewer accepts;
# the test fails on a violation not listed and on a listed one that no longer happens.
KNOWN_VIOLATIONS: dict[str, str] = {}


@dataclass(frozen=True)
class Import:
    source: str  # the importing module, dotted
    target: str  # the imported module, dotted (ours resolved to a module that exists)
    function: str | None  # the enclosing function, if inside one
    type_only: bool  # under `if TYPE_CHECKING:`
    string: bool  # a module name in a string (importlib tables)
    lazy_comment: bool  # the line carries `# lazy:`


def modules_of(root: Path, package: str) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the package under ``root``."""
    found = {}
    for path in sorted((root / package).rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        if "__pycache__" in parts:
            continue
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The longest prefix of ``name`` that is one of our modules (attributes dropped)."""
    parts = name.split(".")
    for n in range(len(parts), 0, -1):
        if ".".join(parts[:n]) in modules:
            return ".".join(parts[:n])
    return None


def imports_of(module: str, path: Path, modules: dict[str, Path], package: str) -> list[Import]:
    source = path.read_text(encoding="utf-8")
    lines = source.splitlines()
    tree = ast.parse(source)
    found: list[Import] = []
    is_pkg = path.name == "__init__.py"

    def visit(node: ast.AST, function: str | None, type_only: bool) -> None:
        for child in ast.iter_child_nodes(node):
            fn, tc = function, type_only
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                fn = child.name if function is None else f"{function}.{child.name}"
            if isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test):
                tc = True
            names: list[str] = []
            if isinstance(child, ast.Import):
                names = [a.name for a in child.names]
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    here = module.split(".") if is_pkg else module.split(".")[:-1]
                    here = here[: len(here) - (child.level - 1)]
                    base = ".".join([*here, base] if base else here)
                # `from pkg import submodule` imports the submodule
                names = [
                    f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                    for a in child.names
                ]
            elif (
                isinstance(child, ast.Constant)
                and isinstance(child.value, str)
                and re.fullmatch(rf"{package}(\.\w+)+", child.value)
                and child.value in modules
            ):
                found.append(Import(module, child.value, fn, tc, True, False))
            elif (  # an importlib table naming a module of a folder beside the package
                isinstance(child, ast.Constant)
                and isinstance(child.value, str)
                and re.fullmatch(rf"({'|'.join(OUTSIDE)})(\.\w+)+", child.value)
            ):
                found.append(Import(module, child.value, fn, tc, True, False))
            for name in names:
                ours = _resolve(name, modules)
                if ours == module:
                    continue
                target = ours or name
                if not ours and name.split(".")[0] == package:
                    target = name  # a module that does not exist: still reported
                # the reason may sit on the import's line or on the line above it
                said = lines[child.lineno - 1] + (
                    lines[child.lineno - 2] if child.lineno > 1 else ""
                )
                found.append(Import(module, target, fn, tc, False, "# lazy:" in said))
            visit(child, fn, tc)

    visit(tree, None, False)
    return found


def floor(module: str, package: str) -> str:
    parts = module.split(".")
    if len(parts) == 1:
        return "facade"
    return FLOOR_OF.get(parts[1], "unknown:" + parts[1])


def violations(root: Path, package: str = "ekfslam") -> set[str]:
    """Every broken rule, as stable one-line keys (no line numbers, so edits do not churn)."""
    modules = modules_of(root, package)
    found: set[str] = set()
    graph: dict[str, set[str]] = {m: set() for m in modules}
    eager: dict[str, set[str]] = {m: set() for m in modules}  # loaded when the module is
    for module, path in modules.items():
        src_floor = floor(module, package)
        if src_floor.startswith("unknown:"):
            found.add(f"unknown-floor: {module}")
        for imp in imports_of(module, path, modules, package):
            top = imp.target.split(".")[0]
            where = f"{module}.{imp.function}" if imp.function else module
            if imp.function and not imp.string:
                if top not in LAZY_OK:
                    found.add(f"function-import: {where} -> {imp.target}")
                elif not imp.lazy_comment:
                    found.add(f"lazy-without-reason: {where} -> {imp.target}")
            if top == "matplotlib" and src_floor not in MATPLOTLIB_FLOORS:
                found.add(f"matplotlib-outside-viz: {module}")
            if top in OUTSIDE:
                found.add(f"package-imports-outside: {module} -> {imp.target}")
            if top != package:
                continue
            if imp.target not in modules:
                found.add(f"missing-module: {module} -> {imp.target}")
                continue
            if not imp.type_only:
                graph[module].add(imp.target)
                if not imp.function and not imp.string:
                    eager[module].add(imp.target)
            dst_floor = floor(imp.target, package)
            if src_floor == "facade":
                if not imp.type_only and not imp.string:  # its name table is loaded lazily
                    found.add(f"facade-eager: {module} -> {imp.target}")
                continue
            allowed = MAY_IMPORT.get(src_floor, set()) | {src_floor}
            if src_floor == "viz" and imp.type_only:
                allowed = allowed | VIZ_TYPES_FROM
            if dst_floor not in allowed:
                found.add(f"floor: {module} ({src_floor}) -> {imp.target} ({dst_floor})")
            in_filter = module.split(".")[1:3] == ["core", "filter"]
            if (
                src_floor in NO_FILTER_FLOORS
                and not in_filter
                and not imp.type_only
                and _is_filter(imp.target)
            ):
                found.add(f"filter: {module} -> {imp.target}")
    found |= {f"cycle: {' <-> '.join(c)}" for c in cycles(graph)}
    found |= filter_reached(modules, eager, package)
    return found


def _is_filter(module: str) -> bool:
    return module.split(".", 1)[-1] in FILTER_MODULES


def filter_reached(modules: dict[str, Path], eager: dict[str, set[str]], package: str) -> set[str]:
    """Modules of the no-filter floors whose import loads the filter through another module."""
    found = set()
    for module in modules:
        if floor(module, package) not in NO_FILTER_FLOORS:
            continue
        if module.split(".")[1:3] == ["core", "filter"]:
            continue
        for hop in sorted(eager[module]):
            if _is_filter(hop):
                continue  # direct: the `filter:` rule reports it
            seen, todo = {hop}, [hop]
            while todo:
                for nxt in eager[todo.pop()] - seen:
                    seen.add(nxt)
                    todo.append(nxt)
            if any(_is_filter(m) for m in seen | {hop}):
                found.add(f"filter-via: {module} (through {hop})")
    return found


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def compare(found: set[str], known: dict[str, str]) -> tuple[list[str], list[str]]:
    """(new violations, allow-list entries that no longer happen)."""
    return sorted(found - set(known)), sorted(set(known) - found)


# ---------------------------------------------------------------------------------------------


def test_the_package_keeps_the_import_rules() -> None:
    new, gone = compare(violations(REPO), KNOWN_VIOLATIONS)
    assert not new, "imports that break ARCHITECTURE.md's rules:\n" + "\n".join(new)
    assert not gone, "fixed, so delete from KNOWN_VIOLATIONS:\n" + "\n".join(gone)


def test_test_files_have_unique_basenames() -> None:
    # pytest's default import mode puts each test folder on sys.path: no __init__.py, one name each
    folders = [REPO / "tests", *(REPO / name / "tests" for name in OUTSIDE)]
    names = [p.name for folder in folders for p in folder.rglob("*.py") if p.name != "conftest.py"]
    assert len(names) == len(set(names)), sorted(n for n in names if names.count(n) > 1)


def _write(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


_TINY = {
    "pkg/__init__.py": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
    "    from pkg.core.models import f\n",
    "pkg/errors.py": "",
    "pkg/core/__init__.py": "",
    "pkg/core/models.py": "from pkg.errors import *\ndef f(): pass\n",
    "pkg/core/filter/__init__.py": "",
    "pkg/core/filter/ekf.py": "from pkg.core import models\n",
    "pkg/logs/__init__.py": "",
    "pkg/logs/runlog.py": "from pkg.core.models import f\n",
    "pkg/analysis/__init__.py": "",
    "pkg/analysis/study.py": "from pkg.logs import runlog\nfrom pkg.core.filter.ekf import *\n",
    "pkg/viz/__init__.py": "",
    "pkg/viz/plots.py": "import matplotlib\nfrom typing import TYPE_CHECKING\n"
    "if TYPE_CHECKING:\n    from pkg.analysis.study import x\n",
    "pkg/vision/__init__.py": "",
    "pkg/vision/detect.py": "def d():\n    import cv2  # lazy: optional, 0.2 s\n",
}


def test_the_checker_passes_a_tiny_package_that_keeps_the_rules(tmp_path: Path) -> None:
    _write(tmp_path, _TINY)
    assert violations(tmp_path, "pkg") == set()


@pytest.mark.parametrize(
    ("path", "code", "expected"),
    [
        (  # a data source loading the filter
            "pkg/logs/runlog.py",
            "from pkg.core.filter.ekf import *\n",
            {"filter: pkg.logs.runlog -> pkg.core.filter.ekf"},
        ),
        (  # upward, and inside a function, and back: a cycle
            "pkg/logs/runlog.py",
            "def g():\n    from pkg.analysis import study\n",
            {
                "floor: pkg.logs.runlog (logs) -> pkg.analysis.study (analysis)",
                "function-import: pkg.logs.runlog.g -> pkg.analysis.study",
                "cycle: pkg.analysis.study <-> pkg.logs.runlog",
            },
        ),
        (  # a data source loading the filter through an upward import
            "pkg/logs/runlog.py",
            "from pkg.analysis import study\n",
            {
                "floor: pkg.logs.runlog (logs) -> pkg.analysis.study (analysis)",
                "filter-via: pkg.logs.runlog (through pkg.analysis.study)",
                "cycle: pkg.analysis.study <-> pkg.logs.runlog",
            },
        ),
        (  # the core importing the filter through a string table
            "pkg/core/models.py",
            "TABLE = ['pkg.core.filter.ekf']\n",
            {
                "filter: pkg.core.models -> pkg.core.filter.ekf",
                "cycle: pkg.core.filter.ekf <-> pkg.core.models",
            },
        ),
        (  # figures drawn outside viz, a heavy import without its reason
            "pkg/analysis/study.py",
            "def plot():\n    import matplotlib\n",
            {
                "matplotlib-outside-viz: pkg.analysis.study",
                "lazy-without-reason: pkg.analysis.study.plot -> matplotlib",
            },
        ),
        (  # viz importing an analysis at run time (types only are allowed)
            "pkg/viz/plots.py",
            "from pkg.analysis.study import x\n",
            {"floor: pkg.viz.plots (viz) -> pkg.analysis.study (analysis)"},
        ),
        (  # the facade importing eagerly
            "pkg/__init__.py",
            "from pkg.core.models import f\n",
            {"facade-eager: pkg -> pkg.core.models"},
        ),
        (  # the package importing the studies beside it, directly or by a command table
            "pkg/analysis/study.py",
            "import studies.robustness\nTABLE = {'x': ('benchmarks.cli.bench', 'help')}\n",
            {
                "package-imports-outside: pkg.analysis.study -> studies.robustness",
                "package-imports-outside: pkg.analysis.study -> benchmarks.cli.bench",
            },
        ),
        (  # a relative import is resolved like an absolute one
            "pkg/core/models.py",
            "from .filter import ekf\n",
            {
                "filter: pkg.core.models -> pkg.core.filter.ekf",
                "filter-via: pkg.logs.runlog (through pkg.core.models)",
                "cycle: pkg.core.filter.ekf <-> pkg.core.models",
            },
        ),
    ],
)
def test_the_checker_reports_a_bad_import(
    tmp_path: Path, path: str, code: str, expected: set[str]
) -> None:
    _write(tmp_path, _TINY)
    with (tmp_path / path).open("a", encoding="utf-8") as f:
        f.write(code)
    assert violations(tmp_path, "pkg") == expected


def test_the_folders_beside_the_package_import_it_never_each_other() -> None:
    """studies/ and benchmarks/: the package and themselves; an import inside a function only
    for an optional heavy dependency, with its reason (the package's rule)."""
    found = set()
    for name in OUTSIDE:
        modules = {**modules_of(REPO, name), **modules_of(REPO, "ekfslam")}
        for module, path in modules_of(REPO, name).items():
            if ".tests" in module:
                continue  # tests import what they test, where they need it
            for imp in imports_of(module, path, modules, name):
                top = imp.target.split(".")[0]
                if top in OUTSIDE and top != name:
                    found.add(f"outside-imports-outside: {module} -> {imp.target}")
                if imp.function and not imp.string and top not in LAZY_OK:
                    found.add(f"function-import: {module}.{imp.function} -> {imp.target}")
                elif imp.function and not imp.string and not imp.lazy_comment:
                    found.add(f"lazy-without-reason: {module}.{imp.function} -> {imp.target}")
    assert not found, "\n".join(sorted(found))


def test_the_wheel_holds_the_package_and_not_the_folders_beside_it() -> None:
    config = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    found = find_packages(REPO, **config["tool"]["setuptools"]["packages"]["find"])
    assert "ekfslam" in found and "ekfslam.core.filter" in found
    assert not [p for p in found if p.split(".")[0] != "ekfslam"], found
    testpaths = config["tool"]["pytest"]["ini_options"]["testpaths"]
    assert testpaths == ["tests", *(f"{name}/tests" for name in OUTSIDE)]


def test_the_allow_list_can_only_shrink() -> None:
    found = {"floor: a -> b", "cycle: a <-> b"}
    known = {"floor: a -> b": "F1", "cycle: a <-> b": "F2", "function-import: c.f -> d": "F3"}
    assert compare(found, known) == ([], ["function-import: c.f -> d"])
    assert compare(found | {"filter: x -> y"}, known)[0] == ["filter: x -> y"]


def _loaded_after(code: str) -> set[str]:
    """The top-level modules a fresh interpreter has loaded after running `code`."""
    probe = f"{code}\nimport sys\nprint(' '.join(sorted({{m.split('.')[0] for m in sys.modules}})))"
    out = subprocess.run(
        [sys.executable, "-c", probe], cwd=REPO, capture_output=True, text=True, check=True
    )
    return set(out.stdout.split())


def test_importing_the_package_without_filtering_loads_no_numba() -> None:
    # a notebook's first cell, a log reader, the alignment: none of them needs the compiled filter
    loaded = _loaded_after(
        "import ekfslam; ekfslam.SEED_ARENA; import ekfslam.logs.runlog, ekfslam.analysis.alignment"
    )
    assert "ekfslam" in loaded
    assert not loaded & {"numba", "llvmlite"}, sorted(loaded & {"numba", "llvmlite"})


def test_the_command_line_help_loads_no_numeric_library() -> None:
    loaded = _loaded_after(
        "import contextlib, io\nfrom ekfslam.cli.main import main\n"
        "with contextlib.redirect_stdout(io.StringIO()): main(['--help'])"
    )
    assert not loaded & {"numpy", "numba", "scipy", "cv2", "matplotlib", "sympy"}, loaded
