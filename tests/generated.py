"""What the generated (hypothesis) tests of bad input share: the budget, the count, the verdict.

The budget is a hypothesis settings profile (registered in tests/conftest.py): ``ci`` (the
default: `CI_EXAMPLES` examples per test, derandomised, so CI sees the same cases every run) or
``long`` (`LONG_EXAMPLES` each, random), chosen by ``EKFSLAM_HYPOTHESIS=long``.

`seen(target)` counts one generated case of a reader or an API function; at the end of the
session pytest prints how many cases each saw (tests/conftest.py collects the counts of every
xdist worker). `verdict(call, names)` is the property every such test asserts: the call ends in
one of our errors whose one-line message names the input, or returns; `within(seconds)` bounds
the time of one case.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import threading
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from hypothesis import strategies as st

from ekfslam.errors import EkfSlamError

CI_EXAMPLES = 60
LONG_EXAMPLES = 1000
#: Seconds one generated case may take (a FIFO read or a loop would take for ever).
CASE_SECONDS = 60.0
#: Where each pytest process writes its counts (set by tests/conftest.py for the session).
COUNTS_DIR_ENV = "EKFSLAM_GENERATED_COUNTS_DIR"

COUNTS: Counter[str] = Counter()


def seen(target: str) -> None:
    """One more generated case for `target` (a reader, or an API function by its name)."""
    COUNTS[target] += 1


def write_counts() -> None:
    """This process's counts, into the session's folder (one file per process)."""
    folder = os.environ.get(COUNTS_DIR_ENV)
    if folder and COUNTS:
        path = Path(folder) / f"counts-{os.getpid()}.json"
        path.write_text(json.dumps(dict(COUNTS)))


def read_counts(folder: Path) -> Counter[str]:
    total: Counter[str] = Counter()
    for path in sorted(folder.glob("counts-*.json")):
        total.update(json.loads(path.read_text()))
    return total


class TookTooLong(Exception):
    pass


@contextlib.contextmanager
def within(seconds: float = CASE_SECONDS) -> Iterator[None]:
    """Fail a case that runs longer than `seconds` (SIGALRM; in the main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum: int, frame: object) -> None:
        raise TookTooLong(f"a generated case took more than {seconds:g} s")

    before = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, before)


def verdict(call: Callable[[], Any], names: tuple[str, ...]) -> tuple[str, Any]:
    """("error", exc) or ("ok", value) for ``call()``; anything else fails the test.

    An error must be one of ours (`EkfSlamError`), a ValueError, TypeError or OSError as our
    hierarchy makes them, with a one-line message of at most 600 characters that names one of
    `names` (the file, the argument or the function).
    """
    try:
        with within():
            value = call()
    except EkfSlamError as exc:
        text = str(exc)
        assert isinstance(exc, ValueError | TypeError | OSError), f"{type(exc).__name__}: {text}"
        assert "\n" not in text.strip(), f"not one line: {text[:300]!r}"
        assert len(text) <= 600, f"a {len(text)}-character message: {text[:200]!r}"
        assert any(n in text for n in names), f"names none of {names}: {text[:300]!r}"
        return "error", exc
    return "ok", value


# ----------------------------------------------------------------------------------- strategies
#: Text a third party puts where a number belongs.
NASTY_CELLS = (
    "",
    " ",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "Infinity",
    "1e308",
    "1e309",
    "-1e309",
    "1e300",
    "-0.0",
    "0x10",
    "1_000",
    "1,5",
    '"1.5"',
    "1.5.2",
    "--1",
    "+1",
    "1e",
    "e3",
    ".",
    "1/2",
    "TRUE",
    "null",
    "\u0661\u0662",  # Arabic-Indic digits
    "\uff11\uff12",  # fullwidth digits
    "\u00b9",  # superscript one
    "1\u00a0",  # a no-break space
    "\x00",
    "9" * 400,
    "1" + "0" * 30,
    "3.0",
    "-1",
    "99999999999999999999",
    "4.9e-324",
)
#: Bytes a third party's file may hold at any place.
NASTY_BYTES = (
    b"\x00",
    b"\xff",
    b"\xfe\xff",
    b"\xef\xbb\xbf",
    b"\r",
    b"\r\n",
    b"\n",
    b"\n\n",
    b",",
    b";",
    b"\t",
    b" ",
    b"#",
    b'"',
    b"nan",
    b"inf",
    b"-",
    b"e",
    b"1e309",
    b"\xc3\xa9",
    b"\xe2\x80\xa8",  # a unicode line separator
    b"\x1a",
)

cells = st.one_of(
    st.sampled_from(NASTY_CELLS),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(2**70), 2**70).map(str),
    st.text(max_size=12),
)


def numbers_of_every_kind() -> st.SearchStrategy[float]:
    """Floats a column may be given: ordinary, tiny, huge, NaN, inf, negative zero."""
    return st.one_of(
        st.floats(-10.0, 10.0),
        st.sampled_from([math.nan, math.inf, -math.inf, -0.0, 1e300, -1e300, 5e-324, 1e15]),
        st.floats(allow_nan=True, allow_infinity=True),
    )
