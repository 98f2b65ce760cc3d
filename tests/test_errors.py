"""ekfslam's errors cross a process boundary as they were raised: a study's ``--jobs`` workers
(joblib) pickle them, and the command line prints the worker's one line, not a traceback."""

from __future__ import annotations

import inspect
import pickle
import signal

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ekfslam import errors

#: every exception class of the module, with a way to make one from drawn text
MADE = {
    errors.InputError: lambda text, line: errors.InputError(f"runs/{text}.csv", line, text),
    errors.OutputError: lambda text, line: errors.OutputError(f"out/{text}.png", text),
    errors.Interrupted: lambda text, line: errors.Interrupted(signal.SIGTERM),
    errors.LabForbidden: lambda text, line: errors.LabForbidden(text),
}


def _classes() -> list[type]:
    return [
        c
        for _, c in inspect.getmembers(errors, inspect.isclass)
        if issubclass(c, BaseException) and c.__module__ == errors.__name__
    ]


@pytest.mark.parametrize("cls", _classes(), ids=lambda c: c.__name__)
@given(text=st.text(min_size=1, max_size=40), line=st.none() | st.integers(1, 10**9))
def test_an_error_pickles_to_the_same_message_and_fields(cls, text, line) -> None:
    """Regression: an InputError raised in a joblib worker reached the user as "InputError.
    __init__() missing 2 required positional arguments", a traceback instead of its line."""
    made = MADE.get(cls, lambda text, line: cls(text))(text, line)
    back = pickle.loads(pickle.dumps(made))
    assert type(back) is cls and str(back) == str(made)
    assert vars(back) == vars(made)
