"""The CSV files of the run format as text: strict reading (errors name the line), exact writing.

`ekfslam.logs.runlog` knows which files a run folder holds and what their values must mean;
this module knows only the text rules of ``data/README.md``: UTF-8, a header that names the
columns, one row per line, plain ASCII numbers (integers for `INTEGER_COLUMNS`). Floats are
written with ``repr`` (the shortest text that reads back to the same bits), optionally rounded
first.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ekfslam.errors import InputError
from ekfslam.files import not_a_file

INTEGER_COLUMNS = ("tag_id", "frame")  # parsed as int64; every other column is a float


def read_lines(path: str | os.PathLike) -> list[str]:
    """The file's lines without BOM, line endings or trailing blank lines."""
    path = Path(path)
    problem = not_a_file(path)  # before reading: a FIFO would block for ever
    if problem is not None:
        raise InputError(path, None, problem)
    try:
        data = path.read_bytes()
    except OSError as err:
        raise InputError(path, None, f"cannot read the file: {err.strerror}") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data.count(b"\n", 0, err.start) + 1
        raise InputError(path, line, f"not UTF-8 text (byte {err.start}); save as UTF-8") from None
    lines = text.removeprefix("\ufeff").splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    return lines


def read_table(path: Path, layouts: dict[str, tuple[str, ...]]) -> tuple[str, list[np.ndarray]]:
    """Check the header against `layouts` and parse the rows: (layout name, one array per column).

    The fast path parses the whole table at once; on any failure the rows are re-scanned one by
    one so that the error names the first bad line.
    """
    lines = read_lines(path)
    expected = " or ".join(repr(",".join(cols)) for cols in layouts.values())
    if not lines:
        raise InputError(path, 1, f"empty file: expected the header {expected} on line 1")
    header = tuple(f.strip() for f in lines[0].split(","))
    matches = [name for name, cols in layouts.items() if cols == header]
    if not matches:
        raise InputError(
            path, 1, _header_problem(header, layouts) + f"; expected header {expected}"
        )
    name, columns = matches[0], layouts[matches[0]]
    body = lines[1:]
    if not body:
        return name, [np.empty(0, _dtype(c)) for c in columns]
    dtype = [(c, _dtype(c)) for c in columns]
    try:
        # numpy's C parser is ~10x faster than float() per cell; it skips blank lines silently,
        # hence the row count check
        table = np.loadtxt(body, dtype=dtype, delimiter=",", comments=None, ndmin=1)
        if len(table) != len(body):
            raise ValueError("blank line")
    except (ValueError, OverflowError) as err:
        _scan_rows(path, body, columns)
        raise InputError(path, None, f"cannot parse the rows: {err}") from None
    return name, [np.ascontiguousarray(table[c]) for c in columns]


def read_columns(path: str | os.PathLike, columns: tuple[str, ...]) -> list[np.ndarray]:
    """One CSV file of the run format: the header must be `columns`; one array per column.

    The text rules of ``data/README.md`` apply (errors name the line); ``tag_id`` and ``frame``
    columns are integers, the others floats. Used for files other modules add to a run, such as
    frames.csv (`ekfslam.logs.frames`).
    """
    return read_table(Path(path), {"table": tuple(columns)})[1]


def _dtype(column: str) -> type:
    return np.int64 if column in INTEGER_COLUMNS else np.float64


def _parse_cell(column: str, text: str) -> None:
    """Raise ValueError unless `text` is a plain ASCII number (an integer for tag_id, frame)."""
    if not text.isascii() or "_" in text:  # float() also takes "1_000" and Arabic digits
        raise ValueError(text)
    if column not in INTEGER_COLUMNS:
        float(text)
    elif not -(2**63) <= int(text) < 2**63:
        raise OverflowError(text)


def _header_problem(header: tuple[str, ...], layouts: dict[str, tuple[str, ...]]) -> str:
    closest = max(layouts.values(), key=lambda cols: len(set(cols) & set(header)))
    missing = [c for c in closest if c not in header]
    unknown = [c for c in header if c not in closest]
    parts = [f"missing column {', '.join(missing)}"] if missing else []
    parts += [f"unknown column {', '.join(map(repr, unknown))}"] if unknown else []
    return f"header {','.join(header)!r}: " + (
        "; ".join(parts) or "columns repeated or out of order"
    )


def _scan_rows(path: Path, body: list[str], columns: tuple[str, ...]) -> None:
    """Raise InputError for the first row that does not parse (the slow, precise path)."""
    for number, line in enumerate(body, start=2):
        fields = [f.strip() for f in line.split(",")]
        if not line.strip():
            raise InputError(path, number, "blank line in the middle of the file")
        if fields[0] == "t":
            raise InputError(
                path,
                number,
                "header line repeated in the middle of the file (two logs pasted together?)",
            )
        if len(fields) != len(columns):
            raise InputError(
                path,
                number,
                f"expected {len(columns)} fields ({','.join(columns)}), "
                f"found {len(fields)} (truncated line?)",
            )
        for column, text in zip(columns, fields, strict=True):
            try:
                _parse_cell(column, text)
            except (ValueError, OverflowError):
                what = "an integer" if column in INTEGER_COLUMNS else "a number"
                raise InputError(path, number, f"{column} is not {what}: {text!r}") from None


# ---------------------------------------------------------------------------------------------
# Writing


def csv_text(
    columns: tuple[str, ...], arrays: list[np.ndarray], decimals: int | None = None
) -> str:
    """The CSV text of `arrays` (one (N,) array per column) under the header `columns`.

    decimals : round every float to that many decimals first (None: every float exactly).
    """
    # tolist() gives Python floats/ints, whose repr is the shortest text that reads back exactly
    cells = [np.asarray(a).tolist() for a in arrays]
    if decimals is not None:
        cells = [[rounded(x, decimals) for x in column] for column in cells]
    rows = [",".join(map(repr, row)) for row in zip(*cells, strict=True)]
    return "\n".join([",".join(columns), *rows]) + "\n"


def rounded(x: float | int, decimals: int) -> float | int:
    """`x` rounded to `decimals` (floats only), and -0.0 as 0.0: a last bit can flip that sign."""
    if isinstance(x, float):
        # Python's round() is correctly rounded (decimal, half to even): the same on every CPU
        return round(x, decimals) + 0.0
    return x
