"""The notebooks' exercises: an answer checked against the expected value, with a verdict."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def check_answer(answer: object, expected: ArrayLike, atol: float = 1e-6) -> bool:
    """Compare an exercise's answer with the expected value and print a verdict.

    Returns True when `answer` has the expected shape and agrees within `atol`; None (not
    answered yet) and anything of the wrong shape print a hint instead of raising.
    """
    if answer is None:
        print("Not answered yet: replace None with your answer and run this cell again.")
        return False
    try:
        got = np.asarray(answer, dtype=float)
        want = np.asarray(expected, dtype=float)
        if got.shape != want.shape:
            print(f"Not yet: the answer has shape {got.shape}, the expected one {want.shape}.")
            return False
        ok = bool(np.allclose(got, want, rtol=0.0, atol=atol))
    except (TypeError, ValueError):
        print(f"Not yet: {answer!r} is not a number or an array of numbers.")
        return False
    print("Right!" if ok else f"Not yet: off by up to {np.max(np.abs(got - want)):.3g}.")
    return ok
