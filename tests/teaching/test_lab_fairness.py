"""The lab's checks are fair to answers in forms the hand-written corpus does not use, and the
grader's wire does not change a verdict.

Two families, both generated:

- *Through the wire.* The grader calls a student's function in a sandbox and reads its answer back
  over JSON frames (`ekfslam.teaching.lab_wire`, `ekfslam.cli.lab_producer.call`,
  `ekfslam.cli.lab_sandbox.read_answer`). `Loopback` is that path with the process left out: every
  right and wrong answer of the corpus gets the same score through it as called directly.
- *Forms and perturbations* (hypothesis). A right answer returned as float32, nested lists,
  tuples of rows, a list for the tuple, 0-d arrays for its numbers scores 1; the same answer
  scaled, shifted, transposed, cut short, NaN, None or text scores less than 1, and the judge never
  fails on it itself (`JudgeFailed`, which would tell the student to ask the instructor).
"""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ekfslam.analysis.lab_key import EXERCISES, hidden_cases
from ekfslam.cli import lab_producer
from ekfslam.cli.lab_sandbox import SandboxAnswer, read_answer
from ekfslam.cli.lab_worker import derives
from ekfslam.teaching.lab_wire import decode, encode
from ekfslam.teaching.verdicts import JudgeFailed, Verdict, run_exercise
from tests.teaching.lab_corpus import CORPUS, RIGHT, WRONG
from tests.teaching.test_lab_corpus import graded, student_function


class Loopback:
    """A sandbox without the process: the call's arguments and its answer each go through the
    JSON frames the real one writes, and the notebook side is the producer's own `call`."""

    def __init__(self, fn) -> None:
        self.fn, self.watching = fn, None

    def call(self, args: list) -> dict:
        sent = json.loads(json.dumps(encode(list(args)), allow_nan=False))
        answer = lab_producer.call(self.fn, list(decode(sent, dataclasses_allowed=True)))
        return read_answer(json.loads(json.dumps(answer, allow_nan=False)))

    def watch(self, name: str) -> bool:
        names = getattr(self.fn, "__globals__", {})
        if not callable(names.get(name)):
            return False
        self.watching = names[name] = lab_producer._Watched(names[name])
        return True

    def watched(self) -> int | None:
        return self.watching.calls if self.watching else None


def through_the_wire(exercise: str, source: str, label: str) -> Verdict:
    fn = student_function(exercise, source, label)
    remote = SandboxAnswer(Loopback(fn), derives([source]))
    return run_exercise(EXERCISES[exercise], remote, graded()[exercise])


ANSWERS = [entry for entry in CORPUS if entry[1] in (RIGHT, WRONG)]


@pytest.mark.parametrize(
    ("exercise", "kind", "label", "source", "expected"),
    ANSWERS,
    ids=[f"{e}-{k}-{label}" for e, k, label, *_ in ANSWERS],
)
def test_the_wire_changes_no_verdict(exercise, kind, label, source, expected) -> None:
    remote = through_the_wire(exercise, source, label)
    local = run_exercise(
        EXERCISES[exercise], student_function(exercise, source, label), graded()[exercise]
    )
    assert (remote.score, remote.passed) == (local.score, local.passed), (remote, local)
    if kind == RIGHT:
        assert remote.score == 1.0, remote.line
    else:
        assert remote.score < 1.0, remote.line


# --- forms and perturbations --------------------------------------------------------------


#: exercises whose answer is numbers (2a and 4a answer with sympy, 8 drives a filter)
NUMERIC = [n for n, ex in EXERCISES.items() if ex.returns and not ex.differentiates]


@functools.cache
def right_answer(exercise: str):
    """The corpus's first right answer to `exercise` in float64, as a function (a float32 one
    turned into lists would lose the dtype that says how precise it is)."""
    _, _, label, source, _ = next(
        e for e in CORPUS if e[0] == exercise and e[1] == RIGHT and "float32" not in e[2]
    )
    return student_function(exercise, source, label)


def _leaf(value: object, form: str) -> object:
    """One number or array of an answer in `form`."""
    array = np.asarray(value, dtype=float)
    if form == "float32":
        return array.astype(np.float32) if array.ndim else np.float32(array)
    if form == "0-d array" and array.ndim == 0:
        return np.array(float(array))
    if form == "nested lists":
        return array.tolist()
    if form == "tuple of rows" and array.ndim >= 1:
        return tuple(np.asarray(row).tolist() for row in array)
    if form == "list of row arrays" and array.ndim == 2:
        return [row.copy() for row in array]
    if form == "column" and array.ndim == 1:
        return array.reshape(-1, 1)
    return array


FORMS = ["float32", "0-d array", "nested lists", "tuple of rows", "list of row arrays", "column"]


def in_form(result: object, form: str, container: str) -> object:
    if isinstance(result, tuple):
        leaves = [_leaf(v, form) for v in result]
        return leaves if container == "list" else tuple(leaves)
    return _leaf(result, form)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    exercise=st.sampled_from(NUMERIC),
    form=st.sampled_from(FORMS),
    container=st.sampled_from(["tuple", "list"]),
)
def test_a_right_answer_in_any_form_scores_full(exercise, form, container) -> None:
    fn = right_answer(exercise)

    def answer(*args):
        return in_form(fn(*args), form, container)

    verdict = run_exercise(EXERCISES[exercise], answer, graded()[exercise])
    assert verdict.score == 1.0, (form, container, verdict.line)


def _perturbed(value: object, how: str, size: float) -> tuple[object, bool]:
    """`value` changed by `how`; False when the change leaves the same numbers (a symmetric
    matrix transposed, a vector of zeros scaled), so the answer may still be right."""
    array = np.asarray(value, dtype=float)
    if how == "scaled":
        out = array * (1.0 + size)
    elif how == "shifted":
        out = array + size
    elif how == "transposed":
        out = array.T.copy()
    elif how == "one entry NaN":
        out = array.copy()
        out.flat[0] = np.nan
        return out, True
    elif how == "cut short":
        return (array[:-1] if array.ndim else np.zeros(0)), True
    elif how == "one extra row":
        return np.concatenate([np.atleast_1d(array), np.atleast_1d(array)[:1]]), True
    elif how == "None":
        return None, True
    else:  # text
        return "I do not know", True
    return out, not np.allclose(out, array, rtol=1e-6, atol=1e-9)


HOWS = [
    "scaled",
    "shifted",
    "transposed",
    "one entry NaN",
    "cut short",
    "one extra row",
    "None",
    "text",
]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    exercise=st.sampled_from(NUMERIC),
    how=st.sampled_from(HOWS),
    size=st.floats(1e-3, 10.0),
    which=st.integers(0, 2),
    form=st.sampled_from(["float64", "nested lists"]),
)
def test_a_wrong_answer_never_scores_full_nor_breaks_the_judge(
    exercise, how, size, which, form
) -> None:
    fn = right_answer(exercise)
    changed: list[bool] = []

    def answer(*args):
        result = fn(*args)
        parts = list(result) if isinstance(result, tuple) else [result]
        k = which % len(parts)
        parts[k], differs = _perturbed(parts[k], how, size)
        changed.append(differs)
        if form == "nested lists":
            parts = [p.tolist() if isinstance(p, np.ndarray) else p for p in parts]
        return tuple(parts) if isinstance(result, tuple) else parts[0]

    try:
        verdict = run_exercise(EXERCISES[exercise], answer, graded()[exercise])
    except JudgeFailed as failed:  # pragma: no cover - the failure this test is for
        pytest.fail(f"the judge of {exercise} failed on an answer {how}: {failed}")
    if any(changed):
        assert verdict.score < 1.0, (how, size, verdict.line)
    assert "raised" not in verdict.line, verdict.line  # the function raised nothing


def test_a_judge_that_fails_is_the_graders_fault_not_the_students() -> None:
    """An exception of the judge's own is `JudgeFailed`, never "your function raised"; an
    exception of the student's function stays the student's."""
    from dataclasses import replace

    twist = EXERCISES["1a"]

    def broken_judge(call, case):
        call(("wheels", case["wheels"]), ("geometry", case["geometry"]))
        raise KeyError("a key the judge expected")

    broken = replace(twist, judge=broken_judge)
    with pytest.raises(JudgeFailed, match="KeyError"):
        run_exercise(broken, right_answer("1a"), graded()["1a"])

    def raises(wheels, geometry):
        raise KeyError("the student's own")

    verdict = run_exercise(twist, raises, graded()["1a"])
    assert verdict.score == 0.0 and "your function raised KeyError" in verdict.line


NELDER_MEAD = """
from scipy.optimize import minimize


def align_map(X, Y):
    def mean_distance(p):
        c, s = np.cos(p[2]), np.sin(p[2])
        moved = X @ np.array([[c, -s], [s, c]]).T + p[:2]
        return np.mean(np.hypot(*(moved - Y).T))

    options = {"xatol": 1e-10, "fatol": 1e-14, "maxiter": 20000}
    return minimize(mean_distance, np.zeros(3), method="Nelder-Mead", options=options).x
"""


@pytest.mark.parametrize("seed", [*range(8), 38])
def test_a_generic_optimiser_passes_exercise_9_on_every_draw(seed: int) -> None:
    """A generic optimiser run to tight tolerances stops a little above eq. (17)'s flat minimum
    (Nelder-Mead up to 6e-11 m, Powell's 9.4e-9 m in a student's answer): right whatever cases
    the release draws (the tolerance once was 1e-9 m, and passing depended on the draw)."""
    fn = student_function("9", NELDER_MEAD, "Nelder-Mead from zero")
    verdict = run_exercise(EXERCISES["9"], fn, hidden_cases(seed)["9"])
    assert verdict.score == 1.0, verdict.line


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**63 - 1))
def test_every_release_seed_draws_its_cases(seed: int) -> None:
    """`lab release` draws the graded cases from a random 63-bit seed; one seed in about 40 once
    drew a 6b case whose heading no sighting turned past π, and the release crashed (seed 38)."""
    update = hidden_cases(seed)["6b"][-1]
    assert update["unwrapped"][2] > np.pi  # the wrapped posterior heading is the test


def test_seed_38_draws_its_cases() -> None:
    assert len(hidden_cases(38)["6b"]) == 5
