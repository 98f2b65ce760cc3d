"""What passes between the lab's grader and a student's sandbox: values as JSON, never pickle.

The grader sends a graded case's inputs (arrays, numbers, the package's dataclasses such as a
`MecanumGeometry` or a `RunLog`); the sandbox sends back what the student's function returned.
The grader reads the student's side as untrusted data: `decode` builds only plain values
(None, bools, numbers, strings, lists, tuples, dicts, numeric numpy arrays) and sympy
expressions, rebuilt by `parse_sympy` from their ``srepr`` text through an allowlist of sympy's
classes with evaluation off, never by ``eval``; anything else the student's function returned
arrives as an `Opaque` naming its type, which no judge takes for an answer. A dataclass is
rebuilt only where `decode` is told it may be (`dataclasses=True`, the sandbox's side).

The frames are a 4-byte big-endian length and that many bytes of UTF-8 JSON (`read_frame`,
`write_frame`); a frame above `MAX_FRAME` bytes is refused.
"""

from __future__ import annotations

import ast
import base64
import dataclasses
import importlib
import json
import os
import select
import struct
import threading
import time
from dataclasses import dataclass

import numpy as np
import sympy

MAX_FRAME = 64 * 2**20  # bytes: a graded run and its covariance fit many times over
MAX_SYMPY = 2 * 2**20  # characters of one sympy expression's srepr
MAX_SYMPY_NODES = 200_000
MAX_INTEGER = 10**15  # a sympy Integer beyond this is no answer of the lab
DTYPES = frozenset(
    "bool int8 int16 int32 int64 uint8 uint16 uint32 uint64 float16 float32 float64 complex64 "
    "complex128".split()
)
#: the sympy names a lab answer's srepr may use
SYMPY_NAMES = frozenset(
    """Symbol Dummy Integer Rational Float Half One Zero NegativeOne Pi E Exp1 ImaginaryUnit
    Add Mul Pow sin cos tan cot sec csc asin acos atan acot atan2 sinh cosh tanh exp log sqrt
    Abs sign Max Min Piecewise ExprCondPair BooleanTrue BooleanFalse true false Tuple
    ImmutableDenseMatrix MutableDenseMatrix ImmutableMatrix Matrix re im conjugate
    StrictGreaterThan StrictLessThan GreaterThan LessThan Equality Unequality And Or Not
    nan oo zoo NaN Infinity NegativeInfinity ComplexInfinity""".split()
)


class WireError(ValueError):
    """A frame or a value that is not what this format allows."""


@dataclass(frozen=True)
class Opaque:
    """What the student's function returned when it was none of the values the wire carries."""

    type_name: str

    def __repr__(self) -> str:
        return f"<a {self.type_name}>"


def encode(value: object, depth: int = 0) -> object:
    """`value` as JSON-able data (see the module). Numpy scalars travel as 0-d arrays, so a
    float32 answer keeps its precision; an object with ``__array__`` is converted here."""
    if depth > 64:
        return {"opaque": "deeply nested value"}
    if isinstance(value, np.ndarray | np.generic):  # first: np.float64 is a float too
        array = np.asarray(value)
        if array.dtype.name not in DTYPES:
            return {"opaque": f"numpy array of {array.dtype.name}"}
        data = np.ascontiguousarray(array).tobytes()
        return {
            "array": array.dtype.name,
            "shape": list(array.shape),
            "data": base64.b64encode(data).decode("ascii"),
        }
    if value is None or isinstance(value, bool | str):
        return value
    if isinstance(value, int):
        return int(value) if abs(value) < 2**63 else {"opaque": "int beyond 64 bits"}
    if isinstance(value, float):
        return {"float": float.__repr__(value)}
    if isinstance(value, list):
        return [encode(v, depth + 1) for v in value]
    if isinstance(value, tuple):
        return {"tuple": [encode(v, depth + 1) for v in value]}
    if isinstance(value, dict):
        return {"dict": [[encode(k, depth + 1), encode(v, depth + 1)] for k, v in value.items()]}
    module = type(value).__module__ or ""
    if module.startswith("sympy"):
        text = sympy.srepr(value)
        if len(text) > MAX_SYMPY:
            return {"opaque": "sympy expression too large"}
        return {"sympy": text}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {
            f.name: encode(getattr(value, f.name), depth + 1) for f in dataclasses.fields(value)
        }
        return {"dataclass": f"{module}:{type(value).__qualname__}", "fields": fields}
    if hasattr(value, "__array__"):
        try:
            return encode(np.asarray(value), depth + 1)
        except Exception:  # a lazy array whose conversion fails: it is still no answer
            return {"opaque": type(value).__name__}
    return {"opaque": type(value).__name__}


def decode(data: object, *, dataclasses_allowed: bool = False, depth: int = 0) -> object:
    """The value `encode` wrote; `dataclasses_allowed` rebuilds the package's dataclasses (the
    sandbox reading the grader's inputs), else a dataclass is refused (`WireError`)."""
    if depth > 64:
        raise WireError("a value nested more than 64 deep")
    if data is None or isinstance(data, bool | str | int):
        return data
    if isinstance(data, list):
        return [decode(v, dataclasses_allowed=dataclasses_allowed, depth=depth + 1) for v in data]
    if not isinstance(data, dict) or len(data) not in (1, 2, 3):
        raise WireError(f"not a value of the lab's wire: {type(data).__name__}")
    again = {"dataclasses_allowed": dataclasses_allowed, "depth": depth + 1}
    if "float" in data:
        return float(str(data["float"]))
    if "array" in data:
        return _array(data)
    if "tuple" in data:
        return tuple(decode(v, **again) for v in _list(data["tuple"]))
    if "dict" in data:
        pairs = _list(data["dict"])
        if not all(isinstance(p, list) and len(p) == 2 for p in pairs):
            raise WireError("a dict that is not a list of pairs")
        out = {}
        for k, v in pairs:
            key = decode(k, **again)
            try:
                out[key] = decode(v, **again)
            except TypeError:
                raise WireError("a dict with an unhashable key") from None
        return out
    if "sympy" in data:
        return parse_sympy(str(data["sympy"]))
    if "opaque" in data:
        return Opaque(str(data["opaque"])[:80])
    if "dataclass" in data and dataclasses_allowed:
        return _dataclass(str(data["dataclass"]), data.get("fields"), again)
    raise WireError(f"not a value of the lab's wire: {sorted(data)}")


def _list(value: object) -> list:
    if not isinstance(value, list):
        raise WireError("expected a list")
    return value


def _array(data: dict) -> np.ndarray:
    dtype, shape = str(data["array"]), data.get("shape")
    if dtype not in DTYPES:
        raise WireError(f"an array of {dtype}")
    if not isinstance(shape, list) or not all(isinstance(n, int) and n >= 0 for n in shape):
        raise WireError("an array with a bad shape")
    if len(shape) > 8:
        raise WireError("an array of more than 8 dimensions")
    raw = base64.b64decode(str(data.get("data", "")), validate=True)
    size = int(np.prod(shape, dtype=np.int64))
    if size * np.dtype(dtype).itemsize != len(raw):
        raise WireError("an array whose data does not fit its shape")
    return np.frombuffer(raw, dtype=dtype).reshape(shape).copy()


def _dataclass(name: str, fields: object, again: dict) -> object:
    module, _, qualname = name.partition(":")
    if not (module == "ekfslam" or module.startswith("ekfslam.")) or not isinstance(fields, dict):
        raise WireError(f"not a dataclass of the package: {name}")
    cls: object = importlib.import_module(module)
    for part in qualname.split("."):
        cls = getattr(cls, part)
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        raise WireError(f"not a dataclass: {name}")
    value = object.__new__(cls)
    for key, field in fields.items():
        object.__setattr__(value, key, decode(field, **again))
    return value


#: one `ast.parse` at a time in this process: CPython 3.11's parser is not thread-safe ("AST
#: constructor recursion depth mismatch" when a Dask worker grades two students in two threads)
_PARSING = threading.Lock()


def parse_source(text: str, mode: str = "exec") -> ast.AST:
    """`ast.parse(text, mode=mode)`, one thread at a time (see `_PARSING`)."""
    with _PARSING:
        return ast.parse(text, mode=mode)


def parse_sympy(text: str) -> object:
    """A sympy expression from its ``srepr`` text, built from `SYMPY_NAMES` only, unevaluated.

    Raises `WireError` on anything else: a name outside the list, an attribute, a lambda, a
    string where a number belongs, an integer beyond `MAX_INTEGER`, more than `MAX_SYMPY_NODES`
    nodes."""
    if len(text) > MAX_SYMPY:
        raise WireError("a sympy expression too large")
    try:
        tree = parse_source(text, mode="eval")
    except (SyntaxError, RecursionError, MemoryError, ValueError):
        raise WireError("not a sympy srepr") from None
    if sum(1 for _ in ast.walk(tree)) > MAX_SYMPY_NODES:
        raise WireError("a sympy expression with too many terms")

    def build(node: ast.AST) -> object:
        if isinstance(node, ast.Constant) and isinstance(node.value, int | float | str | bool):
            if isinstance(node.value, int) and abs(node.value) > MAX_INTEGER:
                raise WireError("an integer too large for a lab answer")
            if isinstance(node.value, str) and len(node.value) > 200:
                raise WireError("a name too long for a symbol")
            return node.value
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            return -build(node.operand)  # type: ignore[operator]
        if isinstance(node, ast.List | ast.Tuple):
            return [build(e) for e in node.elts]
        if isinstance(node, ast.Name) and node.id in SYMPY_NAMES:
            return getattr(sympy, node.id)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            if node.func.id not in SYMPY_NAMES:
                raise WireError(f"{node.func.id} is not a sympy name a lab answer uses")
            fn = getattr(sympy, node.func.id)
            args = [build(a) for a in node.args]
            kwargs = {}
            for k in node.keywords:
                if k.arg is None or not isinstance(k.value, ast.Constant):
                    raise WireError("a keyword that is not a constant")
                kwargs[k.arg] = build(k.value)
            try:
                return fn(*args, **kwargs)
            except (TypeError, ValueError, AttributeError, IndexError) as error:
                raise WireError(f"{node.func.id}: {error}") from None
        raise WireError(f"{type(node).__name__} in a sympy srepr")

    try:
        with sympy.evaluate(False):
            return build(tree.body)
    except RecursionError:
        raise WireError("a sympy expression nested too deep") from None


# --- frames ------------------------------------------------------------------------------


def write_frame(fd: int, message: object) -> None:
    """`message` (JSON-able) as one frame on file descriptor `fd`."""
    body = json.dumps(message, allow_nan=False).encode("utf-8")
    if len(body) > MAX_FRAME:
        body = json.dumps({"error": "frame too large"}).encode("utf-8")
    data = struct.pack(">I", len(body)) + body
    while data:
        written = os.write(fd, data)
        data = data[written:]


def read_frame(fd: int, deadline: float | None = None) -> object:
    """One frame's message from `fd`; `WireError` on a closed pipe, a frame too large, bad JSON,
    or (with `deadline`, a ``time.monotonic()``) when it has not arrived by then."""
    head = _read_exactly(fd, 4, deadline)
    (size,) = struct.unpack(">I", head)
    if size > MAX_FRAME:
        raise WireError(f"a frame of {size} bytes")
    try:
        return json.loads(_read_exactly(fd, size, deadline).decode("utf-8"))
    except (ValueError, RecursionError):
        raise WireError("a frame that is not JSON") from None


def _read_exactly(fd: int, size: int, deadline: float | None) -> bytes:
    chunks, got = [], 0
    while got < size:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                raise WireError("no answer in time")
        chunk = os.read(fd, min(size - got, 2**20))
        if not chunk:
            raise WireError("the sandbox closed its pipe")
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)
