"""The lab's verdicts: how a check runs a student's function and says what is wrong.

A check raises `Wrong` with a message that names where the answer differs (an entry, a block, a
missing wrap) and never the right value; `attempt` turns that, a stub's NotImplementedError and a
crash into one printed line.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

WHEELS = ("ω1 (front-left)", "ω2 (front-right)", "ω3 (rear-left)", "ω4 (rear-right)")
TWIST = ("vx", "vy", "ωz")
POSE_NAMES = ("x", "y", "θ")
CONTROL_NAMES = ("Δux", "Δuy", "Δθ")
RNG_SEED = 15  # random cases are the same on every run: a verdict does not flicker


class Wrong(Exception):
    """An answer that disagrees with the package's; the message says where, not what."""


def attempt(exercise: str, check: Callable[[], None]) -> bool:
    """Run one check and print its verdict: done, not done yet, wrong (and where), or crashed."""
    try:
        check()
    except NotImplementedError:
        print(
            f"Exercise {exercise}: not done yet. Replace the `raise NotImplementedError` with your "
            "code and run the cell again; until then the cells below use the package's version."
        )
        return False
    except Wrong as wrong:
        print(f"Exercise {exercise}: not yet: {wrong} The cells below use the package's version.")
        return False
    except Exception as error:  # the student's code crashed: say how, without a traceback
        print(f"Exercise {exercise}: your function raised {type(error).__name__}: {error}")
        return False
    print(f"Exercise {exercise}: right on every test case. The cells below use your function.")
    return True


def as_array(value: object, shape: tuple[int, ...], what: str) -> Array:
    try:
        got = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise Wrong(f"{what} is {type(value).__name__}, not an array of numbers.") from None
    if got.shape != shape:
        raise Wrong(f"{what} has shape {got.shape}; it should have shape {shape}.")
    return got


def close(a: ArrayLike, b: ArrayLike, atol: float = 1e-9) -> bool:
    return bool(np.allclose(a, b, rtol=1e-9, atol=atol))


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
