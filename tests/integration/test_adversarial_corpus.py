"""The adversarial corpus (tests/adversarial_corpus.py), every case a test: inputs nobody listed
in issue 27's four families (the API's arguments, output targets, signals, plausibility across
files) and a reader's worth of bad files and contradictory options, each with its right answer.

The command line runs in this process (`adversarial_corpus.IN_PROCESS`: no interpreter start per
case); the signal cases, and those that patch ekfslam, run in a fresh one. ``python
tests/adversarial_corpus.py`` scores any checkout with every case in its own process.
"""

from __future__ import annotations

from pathlib import Path

import adversarial_corpus as corpus
import pytest

pytestmark = pytest.mark.slow


def _param(name: str):
    marks = [pytest.mark.shared_data] if corpus.CASES[name].needs == "mrclam" else []
    return pytest.param(name, marks=marks, id=name)


@pytest.fixture(autouse=True)
def _in_process(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(corpus, "IN_PROCESS", True)


def test_the_corpus_covers_every_family() -> None:
    families = {c.family for c in corpus.CASES.values()}
    assert families == set(corpus.FAMILIES)
    assert len(corpus.CASES) >= 300


@pytest.mark.parametrize("name", [_param(n) for n in corpus.CASES])
def test_the_answer_is_right(name: str, tmp_path: Path, request: pytest.FixtureRequest) -> None:
    if corpus.CASES[name].needs == "mrclam":
        request.getfixturevalue("mrclam7")  # skips (or fails in CI) without Dataset 7
    verdict = corpus.run_case(name, tmp_path)
    assert verdict is None, verdict
