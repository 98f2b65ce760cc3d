"""Every command the notebooks and the docs name exists: ``python -m ekfslam|studies|benchmarks X``.

The project's studies and benchmarks left the package for the repository's ``studies/`` and
``benchmarks/`` (issue 24); a text that still says ``python -m ekfslam bench`` sends a student to
a command that is gone. README.md is being rewritten into the documentation site; once it names
the new commands it belongs in `TEXTS` too.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from benchmarks.__main__ import COMMANDS as BENCHMARKS
from ekfslam.cli.main import COMMANDS as EKFSLAM
from studies.__main__ import COMMANDS as STUDIES

REPO = Path(__file__).resolve().parents[2]
TABLES = {"ekfslam": EKFSLAM, "studies": STUDIES, "benchmarks": BENCHMARKS}
NAMED = re.compile(r"python -m (ekfslam|studies|benchmarks) ([a-z][a-z-]*)")


def _texts() -> dict[str, str]:
    texts = {}
    for path in sorted((REPO / "notebooks").rglob("*.ipynb")):
        cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
        texts[str(path.relative_to(REPO))] = "\n".join("".join(c["source"]) for c in cells)
    for path in [
        REPO / "ARCHITECTURE.md",
        REPO / "notebooks" / "INSTRUCTOR.md",
        *sorted((REPO / "docs").rglob("*.md")),
        *(REPO / name / "README.md" for name in ("studies", "benchmarks")),
        *sorted(p for d in ("ekfslam", "studies", "benchmarks") for p in (REPO / d).rglob("*.py")),
    ]:
        if path.is_file():
            texts[str(path.relative_to(REPO))] = path.read_text(encoding="utf-8")
    return texts


TEXTS = _texts()
#: Texts that still name a command that moved, each with why it is not fixed here; an entry whose
#: text no longer names it fails, so the list can only shrink.
KNOWN_STALE: dict[str, tuple[str, str]] = {}


@pytest.mark.parametrize("name", sorted(TEXTS))
def test_every_command_a_text_names_exists(name: str) -> None:
    # a line break inside a name (`python -m ekfslam\n  run`) is folded like Markdown folds it
    text = re.sub(r"\s+", " ", TEXTS[name])
    missing = sorted(
        {f"python -m {m.group(1)} {m.group(2)}" for m in NAMED.finditer(text)}
        - {f"python -m {module} {c}" for module, table in TABLES.items() for c in table}
    )
    stale = [KNOWN_STALE[name][0]] if name in KNOWN_STALE else []
    assert missing == stale, f"{name} names commands that do not exist: {missing}"


def test_the_study_and_benchmark_commands_left_the_package() -> None:
    assert not (set(STUDIES) | set(BENCHMARKS)) & set(EKFSLAM)
    assert set(STUDIES) == {
        "score-mrclam",
        "tune-mrclam",
        "consistency",
        "budget",
        "vision-eval",
        "association-auto",
        "noise-fit",
        "team-mrclam",
    }
    assert set(BENCHMARKS) == {"bench", "loop", "tune", "grading"}
