"""Straight-line code for a small step of the filter, made by running that step on symbols.

One of the filter's steps works on a handful of numbers, many times over:
`ekfslam.core.filter.steps.advance`, one control increment on the pose block (27 numbers in, the
same 27 out), run for every odometry row of a log. Compiled as written, each of its 3x3 products
makes a new array, and the allocations cost several times the arithmetic. So the compiled
filter runs, in its place, code generated from it: `straight_line` calls the step itself on
arrays of sympy symbols (its models too, through their own lines, with `math` read as sympy's
functions and the angle wrap kept as a call), collects what it wrote into its arrays as
expressions, names their common subexpressions (`sympy.cse`) and prints them as assignments: one
branch per combination of the step's flags. Nothing is written by hand: change the step or a
model, and the generated code follows (`ekfslam.core.filter.compile` keeps the source it
generated beside the machine code, named by the digest of every line it came from).
"""

from __future__ import annotations

import itertools
import math
import types
from collections.abc import Callable

import numpy as np
import sympy
from sympy.printing.pycode import PythonCodePrinter

from ekfslam.core.filter.rebinding import interpreted, named, rebind
from ekfslam.geometry import wrap_angle

#: The angle wrap, kept as a call in the generated code (it is not a smooth function to expand).
_WRAP = sympy.Function("wrap_angle")


class NotStraightLine(ValueError):
    """A step that cannot be written as straight-line code for these models: tracing it on
    symbols failed (a branch on a value, ``if abs(w) < 1e-9``; numpy's functions on a symbol),
    or the code it gave does not do what the step's lines do at a test point (a branch the
    symbols took silently, ``if w == 0``). The step then runs compiled as written."""


#: sympy's stand-ins for the functions a model may call, by their `math` names
_SYMPY = {
    **{name: getattr(sympy, name) for name in ("cos", "sin", "tan", "atan2", "sqrt", "exp", "log")},
    "hypot": lambda a, b: sympy.sqrt(a * a + b * b),
}
#: numpy's names for them
_NUMPY_NAMES = {"arctan2": "atan2", **{name: name for name in _SYMPY if name != "atan2"}}


class _Numpy(types.ModuleType):
    """numpy as the traced code reads it: its functions of `_SYMPY` are sympy's, the rest
    (``np.array``, ``np.eye``) numpy's own."""

    def __getattr__(self, name: str) -> object:
        return getattr(np, name)


def _stand_ins() -> dict[int, object]:
    """What the traced code reads in place of `math`, numpy and their functions, by the id of
    the original: a model may name them as ``math.cos``, ``np.cos``, ``from math import cos``,
    or close over them (``cos = math.cos`` in its factory)."""
    shim_math, shim_numpy = types.ModuleType("math"), _Numpy("numpy")
    shim_math.pi = sympy.pi
    swap: dict[int, object] = {id(math): shim_math, id(np): shim_numpy}
    for name, stand_in in _SYMPY.items():
        setattr(shim_math, name, stand_in)
        swap[id(getattr(math, name))] = stand_in
    for np_name, name in _NUMPY_NAMES.items():
        setattr(shim_numpy, np_name, _SYMPY[name])
        swap[id(getattr(np, np_name))] = _SYMPY[name]
    return swap


def _symbolic(fn: Callable, env: dict) -> Callable:
    swap = _stand_ins()
    for name, value in env.items():
        env[name] = swap.get(id(value), value)
    if "wrap_angle" in env:
        env["wrap_angle"] = _WRAP
    # the closure as rebound (a factory's helpers traced too), its math functions sympy's
    cells = tuple(types.CellType(env[name]) for name in fn.__code__.co_freevars)
    return types.FunctionType(fn.__code__, env, fn.__name__, fn.__defaults__, cells or None)


def _symbols(name: str, shape: tuple) -> object:
    if shape == ():
        return sympy.Symbol(name, real=True)
    flat = [sympy.Symbol(f"{name}_{k}", real=True) for k in range(int(np.prod(shape)))]
    return np.array(flat, dtype=object).reshape(shape)


def straight_line(
    fn: Callable, spec: dict[str, tuple | list], models: dict[str, object], name: str
) -> str:
    """The source of a function `name` with fn's arguments that writes into its array arguments
    what fn writes, as straight-line code (see the module).

    spec : what fn takes, by argument: a shape (a tuple: an array of symbols), () (one symbol)
        or a list of the values a flag takes (one branch of code each); a shape's "control" is
        the motion model's `control_size`.
    """
    spec = sized(spec, models)
    source = _trace(fn, spec, models, name)
    _check(fn, spec, models, source, name)
    return source


def sized(spec: dict, models: dict[str, object]) -> dict:
    """spec with each "control" in a shape read as the motion model's `control_size`."""
    k = getattr(models.get("motion"), "control_size", 3)

    def resolve(shape: object) -> object:
        if isinstance(shape, dict):  # a shape by a flag's value
            return {f: {v: resolve(s) for v, s in by.items()} for f, by in shape.items()}
        if isinstance(shape, tuple):
            return tuple(k if n == "control" else n for n in shape)
        return shape

    return {a: resolve(s) for a, s in spec.items()}


def _shapes(spec: dict, flags: dict[str, object]) -> dict[str, tuple]:
    """Each array argument's shape for these flag values: a shape is a tuple, or {flag: {value:
    shape}} when it depends on a flag (advance's N: k x k per second, a 3x3 R otherwise)."""
    out = {}
    for a, s in spec.items():
        if isinstance(s, dict):
            ((flag, by_value),) = s.items()
            s = by_value[flags[flag]]
        if isinstance(s, tuple) and s:
            out[a] = s
    return out


def _trace(fn: Callable, spec: dict, models: dict[str, object], name: str) -> str:
    """`straight_line`'s source, not yet checked."""
    traced = rebind({"fn": fn}, models, _symbolic).fn
    scalars = [a for a, s in spec.items() if s == ()]
    flags = {a: s for a, s in spec.items() if isinstance(s, list)}
    branches = []
    for values in itertools.product(*flags.values()):
        arrays = _shapes(spec, dict(zip(flags, values, strict=True)))
        args = {a: _symbols(a, s) for a, s in arrays.items()}
        args |= {a: sympy.Symbol(a, real=True) for a in scalars}
        args |= dict(zip(flags, values, strict=True))
        before = {a: args[a].copy() for a in arrays}
        try:
            traced(**{a: args[a] for a in spec})
        except Exception as error:  # the models are anyone's code: any error means "cannot"
            raise NotStraightLine(_reason(fn, models, error)) from error
        writes = [
            (a, index, sympy.sympify(value))
            for a in arrays
            for index, value in np.ndenumerate(args[a])
            if value != before[a][index]
        ]
        common, reduced = sympy.cse([value for _, _, value in writes], optimizations="basic")
        reads: set[str] = set()
        for expr in [*(e for _, e in common), *reduced]:
            reads |= {s.name for s in expr.free_symbols}
        condition = " and ".join(f"{a} == {v!r}" for a, v in zip(flags, values, strict=True))
        lines = [f"    if {condition or 'True'}:"]
        for a, shape in arrays.items():  # the entries this branch reads, as floats
            for index in np.ndindex(*shape):
                symbol = f"{a}_{int(np.ravel_multi_index(index, shape))}"
                if symbol in reads:
                    lines.append(f"        {symbol} = {a}[{', '.join(map(str, index))}]")
        lines += [f"        {s} = {_code(e)}" for s, e in common]
        for (a, index, _), expr in zip(writes, reduced, strict=True):
            lines.append(f"        {a}[{', '.join(map(str, index))}] = {_code(expr)}")
        lines.append("        return")
        branches.append("\n".join(lines))
    head = f"def {name}({', '.join(spec)}):"
    return "\n".join([head, *branches, ""])


class _Printer(PythonCodePrinter):
    """Python over floats: `math`'s functions, and `wrap_angle` for the wrap."""

    def _print_Function(self, expr: sympy.Function) -> str:
        if expr.func == _WRAP:
            return f"wrap_angle({self._print(expr.args[0])})"
        return super()._print_Function(expr)


def _code(expr: sympy.Expr) -> str:
    """One expression as Python source (`_Printer`)."""
    return _Printer({"fully_qualified_modules": True, "standard": "python3"}).doprint(expr)


def _reason(fn: Callable, models: dict[str, object], error: BaseException) -> str:
    first = str(error).splitlines()[0] if str(error) else ""
    return f"{_which(fn, models)}: {type(error).__name__}: {first}"


def _which(fn: Callable, models: dict[str, object]) -> str:
    """``advance with motion 'arc', sensor 'range-bearing'``: the step and its models."""
    return f"{fn.__name__} with {named(models)}"


def _check(
    fn: Callable, spec: dict[str, tuple | list], models: dict[str, object], source: str, name: str
) -> None:
    """Raise `NotStraightLine` unless the generated `source` writes what fn's own lines write,
    for every flag combination: at a random point, and at points where one value, one argument
    or every argument is zero (where a model's ``if w == 0`` branch, which a symbol never
    takes, would show)."""
    env = {"math": math, "wrap_angle": wrap_angle}
    exec(compile(source, f"<generated {name}>", "exec"), env)
    generated = env[name]
    readable = rebind({"fn": fn}, models, interpreted).fn
    flags = {a: s for a, s in spec.items() if isinstance(s, list)}
    rng = np.random.default_rng(0)
    for values in itertools.product(*flags.values()):
        shapes = _shapes(spec, dict(zip(flags, values, strict=True)))
        shapes |= {a: () for a, s in spec.items() if s == ()}
        arrays = list(shapes)
        zeros = [(a, index) for a in arrays for index in np.ndindex(*shapes[a])]  # one value
        zeros += [(a, None) for a in arrays] + [("all", None), (None, None)]  # one argument, all
        for where, index in zeros:
            point = {a: rng.uniform(0.1, 1.0, shapes[a]) * rng.choice((-1, 1)) for a in arrays}
            for a in arrays if where == "all" else [where] if where else []:
                if index is None or not shapes[a]:
                    point[a] = point[a] * 0.0
                else:
                    point[a][index] = 0.0
            point = {a: v if shapes[a] else float(v) for a, v in point.items()}
            point |= dict(zip(flags, values, strict=True))
            want, got = _run(readable, point), _run(generated, point)
            for a, w in want.items():
                if not np.allclose(got[a], w, rtol=1e-9, atol=1e-12, equal_nan=True):
                    at = "a random point" if where is None else f"{where}{list(index or ())} = 0"
                    raise NotStraightLine(
                        f"{_which(fn, models)}: the generated code does not write what the "
                        f"step's lines write into {a} at {at} (flags {values})"
                    )


def _run(fn: Callable, point: dict) -> dict:
    """fn called on copies of `point`'s arrays; what it left in them (an error: all NaN)."""
    args = {a: v.copy() if isinstance(v, np.ndarray) else v for a, v in point.items()}
    with np.errstate(all="ignore"):
        try:
            fn(**args)
        except (ArithmeticError, ValueError):  # the generated code divides by a zero
            return {
                a: np.full(np.shape(v), np.nan)
                for a, v in args.items()
                if isinstance(v, np.ndarray)
            }
    return {a: v for a, v in args.items() if isinstance(v, np.ndarray)}
