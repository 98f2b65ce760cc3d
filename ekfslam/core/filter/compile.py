"""The filter's fast path: numba compiles the readable steps themselves, for the chosen models.

`ekfslam.core.filter.steps` (and the iterated update, the association's predictions, JCBB's
search) are written once, as plain numpy in block form. Run as they are, they are the filter a
reader steps through in a debugger. `compiled` hands back the same functions compiled by numba:

1. Each function's source is parsed and every ``a @ b`` becomes ``small_matmul(a, b)``: numba
   implements ``@`` with a BLAS call, whose overhead is ten times the arithmetic of the 2x3 and
   3x3 products a step is made of; compiled, `small_matmul` is three loops, and interpreted it
   is ``@`` itself.
2. The names ``motion`` and ``sensor`` in the steps are bound to the chosen models'
   functions (`ekfslam.core.models.MotionModel`, `SensorModel`), compiled the same way, and so
   is every other function of ekfslam that a compiled function calls, down to the models.
3. Three primitives have a compiled form of their own: `ekfslam.core.filter.symmetric.
   subtract_products`, one loop over Σ instead of numpy's d x d temporary, and
   `ekfslam.core.filter.steps.cholesky` and `positive`, loops where the Python steps call
   numpy (LAPACK for a 2x2 costs more than its arithmetic, compiled; loops cost more than
   LAPACK, interpreted).
4. numba caches the machine code beside the source files (``cache=True``), under a name that
   carries a digest of every source involved and of the models' parameters: a changed model or
   step is compiled afresh, and only the first run on a machine pays the compilation. Each
   digest costs about 2.5 MB there; the cache keeps the `KEEP_DIGESTS` last used (`prune`), so
   a teaching assistant who edits a model fifty times does not leave fifty copies behind.

This module is the only one that imports numba; the filter imports it when asked for the
compiled backend (`ekfslam.core.filter.config.FilterConfig.backend`).
"""

from __future__ import annotations

import ast
import contextlib
import hashlib
import importlib
import importlib.metadata
import importlib.util
import inspect
import os
import re
import sys
import textwrap
import time
import types
import warnings
from collections.abc import Callable
from pathlib import Path

import numba
import numpy as np
from numba import njit
from numba.extending import overload

from ekfslam.core.filter import steps as filter_steps
from ekfslam.core.filter import symmetric
from ekfslam.core.filter.rebinding import called, closure, named, rebind
from ekfslam.errors import ConfigError
from ekfslam.files import atomic_write_text

#: The module that writes straight-line code from a step's lines (it loads sympy: imported only
#: when a step's code is not in the cache yet).
GENERATOR = "ekfslam.core.filter.generate"

#: numba's options for every compiled function: errors as numpy gives them (inf and NaN, which
#: the steps test for), never a Python exception raised from inside a division.
OPTIONS = {"cache": True, "error_model": "numpy", "nogil": True}


def small_matmul(A, B):
    """``A @ B``: what ``@`` becomes in compiled code (see the module)."""
    return A @ B


#: functions compiled by a form of their own, not from their source
PRIMITIVES = frozenset(
    {small_matmul, symmetric.subtract_products, filter_steps.cholesky, filter_steps.positive}
)


@overload(small_matmul, jit_options=OPTIONS)
def _small_matmul(A, B):
    if A.ndim == 2 and B.ndim == 2:
        return _matrix_matrix
    if A.ndim == 2:
        return _matrix_vector
    if B.ndim == 2:
        return _vector_matrix
    return _dot


def _matrix_matrix(A, B):
    n, k = A.shape
    C = np.zeros((n, B.shape[1]))
    for i in range(n):
        for t in range(k):  # the columns innermost: along B's rows (G Σ[r, m]'s n columns)
            a = A[i, t]
            for j in range(B.shape[1]):
                C[i, j] += a * B[t, j]
    return C


def _matrix_vector(A, B):
    n, k = A.shape
    c = np.empty(n)
    for i in range(n):
        total = 0.0
        for t in range(k):
            total += A[i, t] * B[t]
        c[i] = total
    return c


def _vector_matrix(A, B):
    k, m = B.shape
    c = np.empty(m)
    for j in range(m):
        total = 0.0
        for t in range(k):
            total += A[t] * B[t, j]
        c[j] = total
    return c


def _dot(A, B):
    total = 0.0
    for t in range(A.shape[0]):
        total += A[t] * B[t]
    return total


@overload(symmetric.subtract_products, jit_options=OPTIONS, inline="always")
def _subtract_products(Sigma, d, A, B):
    def one_pass(Sigma, d, A, B):  # Σ[i, k] -= Σ_a A[a, i] B[a, k], every k: rows contiguous
        n = A.shape[0]
        for i in range(d):
            row = Sigma[i, :d]
            for a in range(0, n - 1, 2):  # two products a pass: half the reads and writes of Σ
                x, y, b, c = A[a, i], A[a + 1, i], B[a, :d], B[a + 1, :d]
                for k in range(d):
                    row[k] -= x * b[k] + y * c[k]
            if n % 2:
                x, b = A[n - 1, i], B[n - 1, :d]
                for k in range(d):
                    row[k] -= x * b[k]

    return one_pass


@overload(filter_steps.cholesky, jit_options=OPTIONS)
def _cholesky(S):
    def loops(S):  # C[i, j] from S's lower triangle, row by row
        k = S.shape[0]
        C = np.zeros((k, k))
        for i in range(k):
            for j in range(i + 1):
                dot = 0.0
                for t in range(j):
                    dot += C[i, t] * C[j, t]
                total = S[i, j] - dot
                C[i, j] = np.sqrt(total) if i == j else total / C[j, j]
        return C

    return loops


@overload(filter_steps.positive, jit_options=OPTIONS)
def _positive(C):
    def loops(C):  # every entry finite, every pivot > 0, det = (Π pivots)² in (0, inf)
        k = C.shape[0]
        product = 1.0
        for i in range(k):
            for j in range(k):
                if not np.isfinite(C[i, j]):
                    return False
            if not C[i, i] > 0.0:
                return False
            product *= C[i, i]
        det = product * product
        return 0.0 < det < np.inf

    return loops


class _MatMulToCall(ast.NodeTransformer):
    def visit_BinOp(self, node: ast.BinOp) -> ast.AST:
        self.generic_visit(node)
        if isinstance(node.op, ast.MatMult):
            call = ast.Call(ast.Name("small_matmul", ast.Load()), [node.left, node.right], [])
            return ast.copy_location(call, node)
        return node


def _digest(functions: list[Callable], models: dict[str, object]) -> str:
    """A name for this set of sources, the constants they read and the models' parameters (see
    the module, point 4): numba bakes a global's value into the machine code, so a changed
    constant must change the name as a changed line does."""
    h = hashlib.sha256(numba.__version__.encode())
    h.update(inspect.getsource(inspect.getmodule(_digest)).encode())
    h.update(importlib.metadata.version("sympy").encode())  # the generator's (and its code)
    h.update(Path(importlib.util.find_spec(GENERATOR).origin).read_bytes())
    for name, model in models.items():  # the sizes the generated code is written for
        sizes = (getattr(model, "control_size", None), getattr(model, "size", None))
        h.update(f"{name}:{sizes}".encode())
    for fn in functions:
        h.update(f"{fn.__module__}.{fn.__qualname__}".encode())
        h.update(inspect.getsource(fn).encode())
        for cell in fn.__closure__ or ():
            h.update(_stable(cell.cell_contents).encode())
        for name, value in called(fn, models).items():
            if not isinstance(value, types.FunctionType | types.ModuleType) and name not in models:
                h.update(f"{name}={_stable(value)}".encode())
    return h.hexdigest()[:16]


def _stable(value: object, _seen: frozenset = frozenset()) -> str:
    """What a value a compiled function reads is, the same in every process: a function by its
    source and what it closes over (a model's factory makes new ones per call, whose repr
    holds their address), an array by its bytes, anything else by its repr without addresses.
    Else every process would compile afresh, and fill the cache, for a model made by a
    factory; or two tables that differ only in the middle would share machine code."""
    if isinstance(value, np.ndarray):  # numba bakes it in; its repr elides a long one's middle
        return f"array{value.shape}{value.dtype}:{hashlib.sha256(value.tobytes()).hexdigest()}"
    if not isinstance(value, types.FunctionType):
        return _ADDRESS.sub("", repr(value))
    if value in _seen:  # a function that closes over itself (recursion)
        return value.__qualname__
    try:
        source = inspect.getsource(value)
    except (OSError, TypeError):  # made by exec: its bytecode and constants
        source = f"{value.__code__.co_code.hex()}{value.__code__.co_consts!r}"
    seen = _seen | {value}
    cells = ",".join(_stable(c.cell_contents, seen) for c in value.__closure__ or ())
    return f"{value.__qualname__}:{_ADDRESS.sub('', source)}({cells})"


_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def compiled(roots: dict[str, Callable], models: dict[str, object]) -> types.SimpleNamespace:
    """The functions `roots` ({name: function}) compiled by numba, with each name of `models`
    ({"motion": MotionModel, "sensor": SensorModel}) bound to that model (see the module).

    Returns a namespace of numba dispatchers, one per root, by the roots' names.
    """
    functions = closure(roots.values(), models, primitives=PRIMITIVES)
    tag = _digest(functions, models)
    with contextlib.suppress(OSError):  # used now: before its generated step is read (`prune`)
        (_cache_dir() / f"ekfslam_used_{tag}.stamp").touch()
    generated = {fn: _generated(fn, models, tag) for fn in functions if _straight_line(fn)}
    replace = {fn: g for fn, g in generated.items() if g is not None}

    outermost = set(roots.values())

    def build(fn: Callable, env: dict) -> Callable:
        env["small_matmul"] = small_matmul
        tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
        tree = ast.fix_missing_locations(_MatMulToCall().visit(tree))
        ast.increment_lineno(tree, fn.__code__.co_firstlineno - 1)
        exec(compile(tree, inspect.getfile(fn), "exec"), env)
        source = env[fn.__name__]
        source.__qualname__ = f"{fn.__qualname__}_{tag}"
        source.__module__ = fn.__module__
        if fn in outermost:
            return njit(**OPTIONS)(source)
        # inlined where it is called: one machine-code library per root to cache and load
        return njit(inline="always", error_model="numpy")(source)

    steps = rebind(roots, models, build, primitives=PRIMITIVES, replace=replace)
    caches = (getattr(getattr(steps, n), "_cache", None) for n in roots)  # none: JIT disabled
    paths = {getattr(c, "cache_path", None) for c in caches}
    prune({_cache_dir()} | {Path(p) for p in paths if p is not None}, tag)
    for name in roots:
        setattr(steps, name, _FirstCall(steps, name, models))
    return steps


def warm_stamp(roots: dict[str, Callable], models: dict[str, object]) -> Path:
    """The marker ``ekfslam_warm_<digest>.stamp`` that says the cache holds the machine code of
    these roots for these models, as a loop of the filter's steps calls them (``python -m
    ekfslam warm`` writes it once it has called each): a filter whose backend is "auto" loads
    the compiled steps then, in a second, instead of compiling them for a minute
    (`ekfslam.core.filter.backend.auto_steps`)."""
    tag = _digest(closure(roots.values(), models, primitives=PRIMITIVES), models)
    return _cache_dir() / f"ekfslam_warm_{tag}.stamp"


#: How many digests (sets of sources and models, `_digest`) the cache keeps, the last used; one
#: used within `RECENT_S` seconds is kept whatever its rank (another process may be loading it).
KEEP_DIGESTS = 8
RECENT_S = 3600.0
#: A cached file's digest: numba's ``steps.sight_<digest>-496.py311.1.nbc`` (and ``.nbi``), the
#: generated ``ekfslam_generated_advance_<digest>.py``, the markers ``ekfslam_used_<digest>.stamp``
#: and ``ekfslam_warm_<digest>.stamp``.
_DIGEST_IN_NAME = re.compile(r"_([0-9a-f]{16})[-.]")


def prune(folders: set[Path], tag: str) -> list[Path]:
    """Delete the files of every digest in `folders` but `tag` (the one in use), the
    `KEEP_DIGESTS` last used and those used within `RECENT_S`; returns what it deleted. A digest
    is used when a process makes its steps (`compiled` touches its marker; a digest without one
    counts by its newest file). A file another process deletes first, or a folder this one may
    not write, is passed over."""
    used: dict[str, float] = {}
    files: dict[str, list[Path]] = {}
    for folder in folders:
        with contextlib.suppress(OSError):
            for path in folder.iterdir():
                found = _DIGEST_IN_NAME.search(path.name)
                if found is None:
                    continue
                digest = found.group(1)
                files.setdefault(digest, []).append(path)
                with contextlib.suppress(OSError):
                    used[digest] = max(used.get(digest, 0.0), path.stat().st_mtime)
    now, deleted = time.time(), []
    for digest in sorted(used, key=used.__getitem__, reverse=True)[KEEP_DIGESTS:]:
        if digest == tag or now - used[digest] < RECENT_S:
            continue
        for path in files[digest]:
            with contextlib.suppress(OSError):
                path.unlink()
                deleted.append(path)
    return deleted


class ModelNotCompiled(ConfigError):
    """numba cannot compile a model handed to the compiled filter (`FilterConfig.backend`)."""


class _FirstCall:
    """A step's dispatcher until its first call has compiled (or loaded) its machine code: a
    model numba cannot type ends there in one `ModelNotCompiled` naming the model and numba's
    reason, not in numba's page of traceback. It then puts the dispatcher itself in its place,
    so later calls cost nothing more."""

    def __init__(self, steps: types.SimpleNamespace, name: str, models: dict[str, object]):
        self._steps, self._name, self._models = steps, name, models
        self._dispatcher = getattr(steps, name)

    def __call__(self, *args: object) -> object:
        try:
            out = self._dispatcher(*args)
        except numba.core.errors.TypingError as error:
            lines = [line for line in str(error).splitlines() if line.strip()]
            reason = lines[1] if len(lines) > 1 and lines[0].startswith("Failed in") else lines[0]
            raise ModelNotCompiled(
                f"backend='numba': numba cannot compile the filter's {self._name} with "
                f"{named(self._models)}: "
                f"{reason.strip()}; use FilterConfig(backend='python'), or write the model as "
                "plain math on floats (ARCHITECTURE.md, 'Where a new sensor model goes')"
            ) from None
        setattr(self._steps, self._name, self._dispatcher)
        return out

    @property
    def py_func(self) -> Callable:
        """The dispatcher's Python function (what `ekfslam.teaching.tripwire` looks for)."""
        return self._dispatcher.py_func


def _straight_line(fn: Callable) -> dict | None:
    """The argument shapes fn's module declares for it in ``STRAIGHT_LINE``, or None."""
    return getattr(sys.modules[fn.__module__], "STRAIGHT_LINE", {}).get(fn.__name__)


def _generated(fn: Callable, models: dict[str, object], tag: str) -> Callable | None:
    """The straight-line stand-in for fn (`ekfslam.core.filter.generate`): read from the cache
    if it was generated for these sources before, else generated (sympy, about a second) and
    written there. The file is plain Python, to read beside the lines it was made from.

    None when these models cannot be written so (`generate.NotStraightLine`: a branch on a
    value, numpy's functions): fn is then compiled as written, slower and as right, and a
    `SlowStepWarning` says why; the cache keeps the reason, so that sympy runs once."""
    name = f"ekfslam_generated_{fn.__name__}_{tag}"
    path = _cache_dir() / f"{name}.py"
    if not path.is_file():
        generator = importlib.import_module(GENERATOR)
        try:
            source = generator.straight_line(fn, _straight_line(fn), models, fn.__name__)
        except generator.NotStraightLine as why:
            source = f"NOT_GENERATED = {str(why)!r}\n"
        header = (
            f'"""{fn.__module__}.{fn.__qualname__} as straight-line code, generated by '
            f"{GENERATOR} from its lines and the models'.\n\nDo not edit: it is made again "
            'whenever any of them changes (its name carries their digest)."""\n\n'
            "import math\n\nfrom ekfslam.geometry import wrap_angle\n\n\n"
        )
        atomic_write_text(path, header + source)  # another process may be writing it too
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    if hasattr(module, "NOT_GENERATED"):
        warnings.warn(
            f"the compiled filter runs {fn.__name__} as written, not as straight-line code "
            f"(slower, as right): {module.NOT_GENERATED}",
            SlowStepWarning,
            stacklevel=2,
        )
        return None
    return getattr(module, fn.__name__)


class SlowStepWarning(UserWarning):
    """A compiled step runs from its own lines: its models cannot be made straight-line code."""


def _cache_dir() -> Path:
    """Where generated sources go: the package's own ``__pycache__`` when it can be written to
    (a checkout, a user's environment), else the user's cache folder."""
    user = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "ekfslam"
    for folder in (Path(__file__).resolve().parent / "__pycache__", user / "generated"):
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(folder, os.W_OK):
            return folder
    raise OSError("no folder to keep the generated steps in: set XDG_CACHE_HOME")
