"""MRCLAM's .dat text: whitespace-separated numbers with ``#`` headers, read and checked.

`read_table` is fast on a good file (np.loadtxt) and, on a bad one, names the exact line and
problem in an `ekfslam.errors.InputError`; `ekfslam.logs.mrclam.load` reads every file with it.
"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ekfslam.errors import InputError
from ekfslam.files import not_a_file

Array = NDArray[np.float64]

# What np.loadtxt accepts as a number; the slow line-by-line check must agree with it (ASCII
# digits: re's \d also matches Arabic-Indic and fullwidth ones, which np.loadtxt refuses).
_NUMBER = re.compile(r"[+-]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?")
_NON_FINITE = re.compile(r"[+-]?(nan|inf|infinity)", re.IGNORECASE)
_NEWLINE = re.compile(r"\r\n|\r|\n")  # the universal newlines np.loadtxt reads


def require_integers(
    path: Path, table: Array, names: tuple[str, ...], columns: tuple[int, ...]
) -> None:
    for col in columns:
        values = table[:, col]
        bad = np.flatnonzero((values != np.round(values)) | (np.abs(values) > 2**31))
        if bad.size:
            row = int(bad[0])
            raise_at_row(
                path, row, f"{names[col]} {values[row]:g} is not a whole number below 2^31"
            )


def read_table(path: Path, names: tuple[str, ...]) -> Array:
    """Parse a whitespace-separated numeric file into (N, columns) float64, validating it.

    np.loadtxt (C parser) does the fast pass; only when it or the shape/finiteness checks fail
    do we walk the file line by line, to name the exact line.
    """
    problem = not_a_file(path)  # before reading: a FIFO would block for ever
    if problem is not None:
        raise InputError(path, None, problem)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            table = np.loadtxt(path, comments="#", ndmin=2, dtype=np.float64, encoding="utf-8-sig")
    except (ValueError, UnicodeDecodeError) as exc:
        _raise_first_bad_line(path, names, fallback=str(exc))
    except OSError as exc:
        raise InputError(path, None, f"cannot read the file: {exc.strerror or exc}") from None
    if table.size == 0:
        raise InputError(path, None, f"empty file: no data rows ({', '.join(names)})")
    if table.shape[1] != len(names) or not np.isfinite(table).all():
        _raise_first_bad_line(path, names, fallback="malformed table")
    return table


def _data_lines(path: Path) -> list[tuple[int, list[str]]]:
    """(1-based line number, fields) of every line that holds data, as np.loadtxt sees them."""
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise InputError(path, line, f"not text: byte 0x{raw[exc.start]:02x}") from None
    rows = []
    for number, line in enumerate(_NEWLINE.split(text), start=1):
        fields = line.split("#", 1)[0].split()
        if fields:
            rows.append((number, fields))
    return rows


def _raise_first_bad_line(path: Path, names: tuple[str, ...], fallback: str) -> None:
    for number, fields in _data_lines(path):
        if len(fields) != len(names):
            raise InputError(
                path,
                number,
                f"expected {len(names)} columns ({', '.join(names)}), found {len(fields)}",
            )
        for name, field in zip(names, fields, strict=True):
            if _NON_FINITE.fullmatch(field):
                raise InputError(path, number, f"{name} is {field}, not a finite number")
            if not _NUMBER.fullmatch(field):
                raise InputError(path, number, f"{name} is {field!r}, not a number")
            if not math.isfinite(float(field)):
                raise InputError(path, number, f"{name} is {field}, too large to be a number")
    raise InputError(path, None, f"could not parse: {fallback}")


def raise_at_row(path: Path, row: int, problem: str) -> None:
    raise InputError(path, data_line(path, row), problem)


def data_line(path: Path, row: int) -> int:
    """The 1-based line of data row `row` (0-based, as `read_table` returns them) of `path`."""
    return _data_lines(path)[row][0]
