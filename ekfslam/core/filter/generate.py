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
import types
from collections.abc import Callable

import numpy as np
import sympy
from sympy.printing.pycode import PythonCodePrinter

from ekfslam.core.filter.rebinding import rebind

#: The angle wrap, kept as a call in the generated code (it is not a smooth function to expand).
_WRAP = sympy.Function("wrap_angle")


def _math() -> types.ModuleType:
    """`math` as the traced code reads it: sympy's functions and constants."""
    shim = types.ModuleType("math")
    for name in ("cos", "sin", "tan", "atan2", "sqrt", "exp", "log", "pi"):
        setattr(shim, name, getattr(sympy, name))
    shim.hypot = lambda a, b: sympy.sqrt(a * a + b * b)
    return shim


def _symbolic(fn: Callable, env: dict) -> Callable:
    env["math"] = _math()
    if "wrap_angle" in env:
        env["wrap_angle"] = _WRAP
    return types.FunctionType(fn.__code__, env, fn.__name__, fn.__defaults__, fn.__closure__)


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
        or a list of the values a flag takes (one branch of code each).
    """
    traced = rebind({"fn": fn}, models, _symbolic).fn
    arrays = {a: s for a, s in spec.items() if isinstance(s, tuple) and s}
    scalars = [a for a, s in spec.items() if s == ()]
    flags = {a: s for a, s in spec.items() if isinstance(s, list)}
    reads: set[str] = set()
    branches = []
    for values in itertools.product(*flags.values()):
        args = {a: _symbols(a, s) for a, s in arrays.items()}
        args |= {a: sympy.Symbol(a, real=True) for a in scalars}
        args |= dict(zip(flags, values, strict=True))
        before = {a: args[a].copy() for a in arrays}
        traced(**{a: args[a] for a in spec})
        writes = [
            (a, index, sympy.sympify(value))
            for a in arrays
            for index, value in np.ndenumerate(args[a])
            if value != before[a][index]
        ]
        common, reduced = sympy.cse([value for _, _, value in writes], optimizations="basic")
        for expr in [*(e for _, e in common), *reduced]:
            reads |= {s.name for s in expr.free_symbols}
        condition = " and ".join(f"{a} == {v!r}" for a, v in zip(flags, values, strict=True))
        lines = [f"    if {condition or 'True'}:"]
        lines += [f"        {s} = {_code(e)}" for s, e in common]
        for (a, index, _), expr in zip(writes, reduced, strict=True):
            lines.append(f"        {a}[{', '.join(map(str, index))}] = {_code(expr)}")
        lines.append("        return")
        branches.append("\n".join(lines))
    loads = []
    for a, shape in arrays.items():
        for index in np.ndindex(*shape):
            symbol = f"{a}_{int(np.ravel_multi_index(index, shape))}"
            if symbol in reads:
                loads.append(f"    {symbol} = {a}[{', '.join(map(str, index))}]")
    head = f"def {name}({', '.join(spec)}):"
    return "\n".join([head, *loads, *branches, ""])


class _Printer(PythonCodePrinter):
    """Python over floats: `math`'s functions, and `wrap_angle` for the wrap."""

    def _print_Function(self, expr: sympy.Function) -> str:
        if expr.func == _WRAP:
            return f"wrap_angle({self._print(expr.args[0])})"
        return super()._print_Function(expr)


def _code(expr: sympy.Expr) -> str:
    """One expression as Python source (`_Printer`)."""
    return _Printer({"fully_qualified_modules": True, "standard": "python3"}).doprint(expr)
