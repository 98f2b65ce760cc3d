"""The adversarial corpus (`tests/teaching/lab_corpus.py`) through the lab's checks: every
correct answer in another form passes, on the notebook's cases and on graded cases it never saw;
every wrong one scores less than 1 and the notebook's line names its mistake; every call into the
package's own implementation scores 0 and says so."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp

from ekfslam.analysis.lab_key import EXERCISES, hidden_cases
from ekfslam.teaching import derivations
from ekfslam.teaching.verdicts import RNG_SEED, run_exercise
from tests.teaching.lab_corpus import CHEAT, CORPUS, RIGHT, WRONG

KEY_SEED = 2026  # any seed: the graded cases of one release


@functools.cache
def graded() -> dict[str, list[dict]]:
    return hidden_cases(KEY_SEED)


def student_function(exercise: str, source: str, label: str):
    names = {"np": np, "sp": sp}
    names |= {s: getattr(derivations, s) for s in ("x", "y", "theta", "du_x", "du_y", "dtheta")}
    names |= {s: getattr(derivations, s) for s in ("m_x", "m_y")}
    exec(compile(source, f"<{exercise}: {label}>", "exec"), names)
    return names[EXERCISES[exercise].function]


def test_the_corpus_is_large_and_covers_every_exercise() -> None:
    assert len(CORPUS) >= 60
    assert {e for e, *_ in CORPUS} == set(EXERCISES)
    kinds = [k for _, k, *_ in CORPUS]
    assert kinds.count(RIGHT) >= 20 and kinds.count(WRONG) >= 20 and kinds.count(CHEAT) >= 10


@pytest.mark.parametrize(
    ("exercise", "kind", "label", "source", "expected"),
    CORPUS,
    ids=[f"{e}-{k}-{label}" for e, k, label, *_ in CORPUS],
)
def test_the_checks_grade_the_corpus(exercise, kind, label, source, expected) -> None:
    ex = EXERCISES[exercise]
    fn = student_function(exercise, source, label)
    seen = run_exercise(ex, fn, ex.make_cases(np.random.default_rng(RNG_SEED)))
    unseen = run_exercise(ex, fn, graded()[exercise])
    if kind == RIGHT:
        assert seen.right and unseen.right, (seen.line, unseen.line)
        assert unseen.score == 1.0
    elif kind == WRONG:
        assert not seen.right and unseen.score < 1.0, (seen.line, unseen.line)
        assert expected in seen.line, seen.line
    else:
        assert seen.score == 0.0 and unseen.score == 0.0
        assert "you called the package's" in seen.line and expected in seen.line, seen.line
        assert "write it yourself" in seen.line
