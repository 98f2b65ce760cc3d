"""The lab's verdicts: how a check runs a student's function and says what is wrong.

An exercise (`Exercise`) is its cases (inputs and the values a right answer gives, made from a
random generator: the notebook's check draws them with a fixed seed, the grader with one drawn at
release time, so the graded cases are ones the student never saw) and a judge that runs the
student's function on one case and raises `Wrong` with a message that names where the answer
differs (an entry, a block, a missing wrap), never the right value. `run_exercise` runs every
case and turns the outcome into one `Verdict`: right on every case, not done yet (a stub), wrong
(the first case's message; the score is the share of cases right), crashed, a constant answer
(0), or a call into the package's own implementation of the exercise (0: the tripwire of
`ekfslam.teaching.tripwire`). `attempt` prints the notebook's line for it.

Every call of the student's function gets copies of its inputs; one it changed in place is named
("your function changed the Σ it was given"). An answer of lower precision (float32) is compared
within its own precision: the tolerances scale with its dtype's machine epsilon.
"""

from __future__ import annotations

import contextlib
import copy
import io
import warnings
from collections.abc import Callable, Iterable, Iterator
from contextvars import ContextVar
from dataclasses import dataclass, field

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ekfslam.teaching import tripwire

Array = NDArray[np.float64]

WHEELS = ("ω1 (front-left)", "ω2 (front-right)", "ω3 (rear-left)", "ω4 (rear-right)")
TWIST = ("vx", "vy", "ωz")
POSE_NAMES = ("x", "y", "θ")
CONTROL_NAMES = ("Δux", "Δuy", "Δθ")
RNG_SEED = 15  # the notebook's cases are the same on every run: a verdict does not flicker
TOLERANCE = 1e-9  # relative and absolute, for a float64 answer
ULPS = 1000  # a lower-precision answer may be off by this many of its own epsilons

#: the machine epsilon of the least precise answer seen in the current exercise
_EPSILON: ContextVar[float] = ContextVar("epsilon", default=float(np.finfo(np.float64).eps))


class Wrong(Exception):
    """An answer that disagrees with the right one; the message says where, not what."""


class NotDone(Exception):
    """The student's function is still the stub."""


class Tripped(Wrong):
    """The student's function called the package's own implementation of the exercise."""


@dataclass(frozen=True)
class Verdict:
    """One exercise's outcome: `score` is the share of cases right (0 after the tripwire or a
    constant answer), `line` what the check prints."""

    exercise: str
    score: float
    passed: int
    total: int
    line: str
    done: bool = True

    @property
    def right(self) -> bool:
        return self.done and self.passed == self.total and self.score == 1.0


@dataclass(frozen=True)
class Exercise:
    """An exercise of the lab: `make_cases(rng)` gives its cases (dicts of inputs and right
    values), `judge(call, case)` runs the student's function through `call` on one case and
    raises `Wrong` where it differs. `allowed()` names what of the package the function may call
    (functions, classes, modules); `numeric` answers must vary with their inputs;
    `differentiates`: sympy must derive the answer (`.jacobian`, `.diff`); a function that
    `returns` nothing (exercise 8) is judged by what it did; `session(fn)` wraps every case
    (exercise 6b watches the student's `joseph`, named by `watches`) and may raise `Wrong` when
    it ends.

    While the lab is graded the function runs in a sandbox (`ekfslam.cli.lab_sandbox`) that
    holds of the package only the modules `keeps` names (and what they import), with the
    functions of `denies` (``module:qualname``) raising: the package's own answer and whatever
    does the same work are absent there."""

    number: str
    function: str
    make_cases: Callable[[np.random.Generator], list[dict]]
    judge: Callable[[Callable[..., object], dict], None]
    allowed: Callable[[], Iterable[object]] = tuple
    numeric: bool = True
    differentiates: bool = False
    returns: bool = True
    session: Callable[[Callable], contextlib.AbstractContextManager] | None = None
    watches: str | None = None
    keeps: tuple[str, ...] = ()
    denies: tuple[str, ...] = ()


class Driven:
    """An input the student's function drives rather than reads (exercise 8's filter): the
    function gets `build()`'s object, and the judge gets `snapshot(obj)` afterwards in place of
    the function's return value. Subclasses say what is built."""

    def build(self) -> object:
        raise NotImplementedError

    def snapshot(self, built: object) -> object:
        raise NotImplementedError


class Remote:
    """A student's function that runs elsewhere (the grader's sandbox): `invoke(args)` returns
    {"result"} or {"raised", "message", "forbidden"} with "mutated"; `differentiates` is what
    the grader read of the answer's source; `session(name)` watches a notebook function."""

    differentiated: bool = False

    def invoke(self, args: list) -> dict:
        raise NotImplementedError

    def session(self, exercise: Exercise) -> contextlib.AbstractContextManager:
        return contextlib.nullcontext()


class Unanswered(Exception):
    """Where a `Remote` function runs could not answer (the grader's sandbox died or ran out of
    time): no verdict on the function, the grader says why."""


class Raised(Exception):
    """What a student's function raised in the sandbox (its type's name and message)."""

    def __init__(self, ename: str, message: str) -> None:
        super().__init__(message)
        self.ename = ename


class JudgeFailed(Unanswered):
    """The check itself failed on a case (its own error, not the student's function's): no
    verdict on the function; the student is told to ask the instructor, who is told the error."""


#: what a student's function may raise that means something to the judge (a stub, a verdict)
_PASSING = (NotImplementedError, Wrong, NotDone, Unanswered)


@dataclass
class _Calls:
    """The student's function as the judge calls it: copies in, tripwire on, results kept."""

    fn: Callable
    allowed: frozenset
    returns: bool = True
    results: list = field(default_factory=list)
    differentiated: bool = False

    def __call__(self, *named: tuple[str, object]) -> object:
        if isinstance(self.fn, Remote):
            return self._remote(named)
        originals = [value for _, value in named]
        built = {i: v.build() for i, v in enumerate(originals) if isinstance(v, Driven)}
        given = [built[i] if i in built else copy.deepcopy(v) for i, v in enumerate(originals)]
        with warnings.catch_warnings(), contextlib.redirect_stderr(io.StringIO()):
            warnings.simplefilter("ignore")  # a warning on stderr would cost the grade
            try:
                result, watch = tripwire.call_watched(self.fn, tuple(given), self.allowed)
            except _PASSING:
                raise
            except Exception as error:  # the student's own: told as theirs, never the judge's
                raise Raised(type(error).__name__, str(error)) from None
        if watch.forbidden:
            raise Tripped(
                f"you called the package's {watch.forbidden[0]}: write it yourself."
            ) from None
        self.differentiated |= watch.differentiated
        for i, ((name, original), after) in enumerate(zip(named, given, strict=True)):
            if i not in built and not _same(original, after):
                raise _changed(name)
        for i, thing in built.items():
            return self._keep(originals[i].snapshot(thing), driven=True)
        return self._keep(result)

    def _remote(self, named: tuple[tuple[str, object], ...]) -> object:
        answer = self.fn.invoke([value for _, value in named])
        self.differentiated |= self.fn.differentiated
        if answer.get("forbidden"):
            what = str(answer.get("message", "")).removeprefix("the package's ")
            what = what.split(" is not available", 1)[0]
            raise Tripped(f"you called the package's {what}: write it yourself.")
        if "result" not in answer:
            ename, message = str(answer.get("raised")), str(answer.get("message", ""))
            if ename == "NotImplementedError":
                raise NotImplementedError(message)
            if ename == "Wrong":
                raise Wrong(message)
            raise Raised(ename, message)
        for i in answer["mutated"]:
            if 0 <= i < len(named) and not isinstance(named[i][1], Driven):
                raise _changed(named[i][0])
        return self._keep(answer["result"], driven=any(isinstance(v, Driven) for _, v in named))

    def _keep(self, result: object, driven: bool = False) -> object:
        """`result` for the judge; a driven input's snapshot is no return value (the function
        itself returns nothing), so the results hold None for it."""
        if result is None and self.returns:
            raise NotDone
        self.results.append(None if driven else result)
        return result


def _changed(name: str) -> Wrong:
    return Wrong(
        f"your function changed the {name} it was given: compute a new array "
        "(np.array(x) copies one) and leave its inputs as they were."
    )


def _same(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b, equal_nan=True))
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if hasattr(a, "__dataclass_fields__") and type(a) is type(b):
        return all(_same(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return True


def _constant(results: list) -> bool:
    """True when every result is the same numbers (a function that ignores its inputs)."""
    try:
        first = [np.asarray(r, dtype=float) for r in _flat(results[0])]
        return all(
            len(first) == len(_flat(r))
            and all(
                a.shape == np.shape(b) and np.array_equal(a, np.asarray(b, dtype=float))
                for a, b in zip(first, _flat(r), strict=True)
            )
            for r in results[1:]
        )
    except (TypeError, ValueError):
        return False


def _zeros(result: object) -> bool:
    try:
        return all(not np.any(np.asarray(r, dtype=float)) for r in _flat(result))
    except (TypeError, ValueError):
        return False


def _flat(result: object) -> list:
    return list(result) if isinstance(result, tuple) else [result]


@contextlib.contextmanager
def _precision() -> Iterator[None]:
    token = _EPSILON.set(float(np.finfo(np.float64).eps))
    try:
        yield
    finally:
        _EPSILON.reset(token)


def run_exercise(exercise: Exercise, fn: Callable, cases: list[dict]) -> Verdict:
    """Run `fn` on every case of `exercise` and judge it (see the module)."""
    n = exercise.number
    calls = _Calls(fn, tripwire.code_objects(exercise.allowed()), exercise.returns)
    passed, wrong, crashed = 0, [], []
    if isinstance(fn, Remote):
        session = fn.session(exercise)
    elif exercise.session:
        session = exercise.session(fn)
    else:
        session = contextlib.nullcontext()
    with _precision():
        try:
            with session:
                for case in cases:
                    try:
                        exercise.judge(calls, case)
                        passed += 1
                    except (Tripped, Unanswered):
                        raise
                    except (Wrong, NotDone) as outcome:
                        if isinstance(outcome, NotDone) and not any(
                            r is not None for r in calls.results
                        ):
                            raise
                        wrong.append(str(outcome) or "your function returned None.")
                    except NotImplementedError:
                        raise NotDone from None
                    except Raised as error:
                        crashed.append(f"{error.ename}: {error}")
                    except Exception as error:  # the student's errors arrive as Raised
                        raise JudgeFailed(f"{type(error).__name__}: {error}") from error
        except NotDone:
            return Verdict(n, 0.0, 0, len(cases), _not_done(n), done=False)
        except Tripped as tripped:
            return Verdict(n, 0.0, 0, len(cases), f"Exercise {n}: {tripped}")
        except Wrong as wrong_whole:  # the session's own verdict (exercise 6b's joseph)
            return Verdict(n, 0.0, passed, len(cases), f"Exercise {n}: not yet: {wrong_whole}")
    total = len(cases)
    if exercise.differentiates and passed and not calls.differentiated:
        return Verdict(
            n,
            0.0,
            0,
            total,
            f"Exercise {n}: not yet: your matrices are typed in, not derived: let sympy "
            "differentiate the model (its .jacobian([...]) or sp.diff).",
        )
    if exercise.numeric and len(calls.results) > 1 and _constant(calls.results):
        zeros = _zeros(calls.results[0])
        what = "zeros" if zeros else "the same answer"
        return Verdict(
            n,
            0.0,
            0,
            total,
            f"Exercise {n}: not yet: your function returns {what} whatever its inputs: compute "
            "the answer from them.",
        )
    if crashed and not passed and not wrong:
        return Verdict(n, 0.0, 0, total, f"Exercise {n}: your function raised {crashed[0]}")
    if wrong or crashed:
        message = wrong[0] if wrong else f"your function raised {crashed[0]}"
        return Verdict(n, passed / total, passed, total, f"Exercise {n}: not yet: {message}")
    return Verdict(n, 1.0, total, total, f"Exercise {n}: right on every test case.")


def _not_done(n: str) -> str:
    return (
        f"Exercise {n}: not done yet. Write your code where the stub is and run the cell "
        "again; until then the cells below use the package's version."
    )


def attempt(exercise: Exercise, fn: Callable, cases: list[dict] | None = None) -> bool:
    """The notebook's check: run the exercise's cases (its fixed ones unless given) and print
    one line; True when every case is right, so the next cells can use the student's function."""
    if cases is None:
        cases = exercise.make_cases(np.random.default_rng(RNG_SEED))
    try:
        verdict = run_exercise(exercise, fn, cases)
    except JudgeFailed as failed:
        print(
            f"Exercise {exercise.number}: the check could not judge your answer (its own error, "
            f"not yours: {failed}); please tell your instructor. The cells below use the "
            "package's version."
        )
        return False
    if verdict.right:
        print(f"{verdict.line} The cells below use your function.")
    elif not verdict.done:
        print(verdict.line)
    elif verdict.line.split(": ", 1)[1].startswith("your function raised"):
        print(verdict.line)
    else:
        print(f"{verdict.line} The cells below use the package's version.")
    return verdict.right


def _note_precision(dtype: np.dtype) -> None:
    if np.issubdtype(dtype, np.floating) or np.issubdtype(dtype, np.complexfloating):
        eps = float(np.finfo(dtype).eps)
        if eps > _EPSILON.get():
            _EPSILON.set(eps)


def as_array(value: object, shape: tuple[int, ...], what: str) -> Array:
    """`value` (an array of any float dtype, a list, a tuple, a sympy matrix) as a float64 array
    of `shape`; a column or row where a vector belongs is taken as the vector."""
    try:
        raw = np.asarray(value)
        if raw.dtype == object:
            raw = np.asarray(np.asarray(value, dtype=object).tolist(), dtype=float)
        _note_precision(raw.dtype)
        got = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise Wrong(f"{what} is {type(value).__name__}, not an array of numbers.") from None
    if got.shape != shape and got.size == int(np.prod(shape)) and len(shape) == 1:
        if got.squeeze().shape == shape:
            got = got.reshape(shape)
    if got.shape != shape:
        raise Wrong(f"{what} has shape {got.shape}; it should have shape {shape}.")
    return got


def close(a: ArrayLike, b: ArrayLike, atol: float = TOLERANCE) -> bool:
    """a and b agree to 1e-9 (relative and absolute), or within the precision of the least
    precise answer of this exercise (float32: ULPS of its epsilon, relative to b's size)."""
    eps = _EPSILON.get()
    if eps <= float(np.finfo(np.float64).eps):
        return bool(np.allclose(a, b, rtol=TOLERANCE, atol=atol))
    loose = ULPS * eps
    scale = float(np.max(np.abs(b))) if np.size(b) else 0.0
    return bool(np.allclose(a, b, rtol=max(TOLERANCE, loose), atol=max(atol, loose * scale)))


def entry_verdict(got: Array, want: Array, name: str, rows: tuple, cols: tuple) -> None:
    """Raise Wrong naming the first entry of a matrix that differs (and whether by its sign)."""
    bad = [(i, j) for i in range(want.shape[0]) for j in range(want.shape[1])]
    bad = [(i, j) for i, j in bad if not close(got[i, j], want[i, j])]
    if not bad:
        return
    i, j = bad[0]
    others = f" ({len(bad) - 1} other entries are wrong too)" if len(bad) > 1 else ""
    how = "has the wrong sign" if close(got[i, j], -want[i, j]) else "is wrong"
    raise Wrong(f"{name}[{i}, {j}] (row {rows[i]}, column {cols[j]}) {how}{others}.")


def evaluate(expr: object, values: dict[str, float], what: str) -> Array:
    """A sympy matrix at numbers, its symbols matched by name (x y theta du_x du_y dtheta)."""
    if not isinstance(expr, sp.MatrixBase):
        raise Wrong(f"{what} is a {type(expr).__name__}; it should be a sympy Matrix.")
    unknown = sorted(s.name for s in expr.free_symbols if s.name not in values)
    if unknown:
        raise Wrong(f"{what} uses {', '.join(unknown)}, which is not a pose or control symbol.")
    subs = {s: values[s.name] for s in expr.free_symbols}
    return np.array(expr.subs(subs).evalf(), dtype=float)
