"""Strict JSON for our files: parsing with limits and line numbers, and a deterministic writer.

Python's `json` accepts what a run file must not hold and fails on some of it with errors a
student cannot act on. `load_json` refuses a key given twice, ``NaN`` and ``Infinity``, an integer
of more than `MAX_DIGITS` digits (``int()`` would refuse it with a bare ``ValueError``) and nesting
deep enough to exhaust the recursion limit; each refusal is one `ekfslam.errors.InputError` naming
the line of the problem. `dump_json` writes sorted keys, no NaN, numpy values as plain numbers.
What the values must mean (the schema of run.json) is `ekfslam.logs.runjson`'s.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from ekfslam.errors import InputError

#: The most digits an integer may have (Python refuses to parse more than 4,300; beyond 309 it is
#: no float either, which the checks of each key report).
MAX_DIGITS = 1000


class _JsonProblem(Exception):
    def __init__(self, token: str, problem: str, occurrence: int = 0) -> None:
        super().__init__(problem)
        self.token, self.problem, self.occurrence = token, problem, occurrence


def _no_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict:
    seen: dict[str, Any] = {}
    for key, value in pairs:
        if key in seen:
            raise _JsonProblem(f'"{key}"', f"key {key!r} appears twice", occurrence=1)
        seen[key] = value
    return seen


def _no_constants(name: str) -> float:
    raise _JsonProblem(name, f"{name} is not allowed: every number must be finite")


def _int_of(text: str) -> int:
    # json would hand a 5,000-digit integer to int(), which refuses it with a bare ValueError
    if len(text.lstrip("-")) > MAX_DIGITS:
        raise _JsonProblem(text[:40], f"an integer of {len(text)} digits is too large a number")
    return int(text)


def _deepest_line(text: str, limit: int = 100) -> int | None:
    """1-based line where brackets first nest deeper than `limit` (strings are not skipped)."""
    depth = 0
    for i, ch in enumerate(text):
        depth += (ch in "[{") - (ch in "]}")
        if depth > limit:
            return text.count("\n", 0, i) + 1
    return None


def line_of(text: str, token: str, occurrence: int = 0) -> int | None:
    """1-based line of the `occurrence`-th appearance of `token` (a best effort for messages)."""
    hits = [m.start() for m in re.finditer(re.escape(token), text)]
    return text.count("\n", 0, hits[occurrence]) + 1 if len(hits) > occurrence else None


def load_json(text: str, path: Path, what: str) -> Any:
    """The JSON document `text` (the file `path`, holding `what`), or `InputError` with its line.

    Parameters
    ----------
    text : the file's text, lines joined by ``"\\n"``.
    path : the file, for the message.
    what : what the file holds, for the message on nesting ("run metadata").
    """
    try:
        return json.loads(
            text,
            object_pairs_hook=_no_duplicate_keys,
            parse_constant=_no_constants,
            parse_int=_int_of,
        )
    except RecursionError:
        line = _deepest_line(text)
        raise InputError(path, line, f"nested too deeply to be {what}") from None
    except json.JSONDecodeError as err:
        raise InputError(
            path, err.lineno, f"invalid JSON: {err.msg} (column {err.colno})"
        ) from None
    except _JsonProblem as err:
        raise InputError(path, line_of(text, err.token, err.occurrence), err.problem) from None


def is_number(value: Any) -> bool:
    """True for a finite JSON number (not a bool, not an integer beyond the largest float)."""
    if not isinstance(value, int | float) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an integer beyond the largest float
        return False


def shown(value: Any) -> str:
    """`value` as JSON for a message, cut to 60 characters (a huge integer stays readable)."""
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _plain(value: Any) -> Any:
    """json.dumps hook: numpy scalars and arrays become plain numbers and lists."""
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON data")


def dump_json(value: Any, indent: int | None = None) -> str:
    """`value` as JSON text: sorted keys, no NaN (`ValueError`), numpy values as plain numbers.

    Without `indent`, one line with ``", "`` between items; with it, one item per line. A value
    that is not JSON data raises `TypeError`.
    """
    separators = (",", ": ") if indent else (", ", ": ")
    return json.dumps(
        value,
        sort_keys=True,
        allow_nan=False,
        default=_plain,
        indent=indent,
        separators=separators,
        ensure_ascii=False,
    )
