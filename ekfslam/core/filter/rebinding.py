"""Copies of functions whose model names are bound again: how the steps are made for a model.

The filter's steps call their models by name (``motion.f``, ``sensor.h``). `rebind` copies each
step, and every function of ekfslam (or of a model's module) it calls, down to the models, with
those names bound to other models; `ekfslam.core.filter.backend` runs the copies as they are,
and `ekfslam.core.filter.compile` compiles them. `closure` lists what would be copied.
"""

from __future__ import annotations

import dis
import types
from collections.abc import Callable, Iterable


def _model_modules(models: dict[str, object]) -> set[str]:
    return {
        v.__module__
        for model in models.values()
        for v in vars(model).values()
        if isinstance(v, types.FunctionType)
    }


def _ours(value: object, modules: set[str], primitives: frozenset) -> bool:
    """A function whose source is ours to bind and compile: ekfslam's, or a model's module's."""
    return (
        isinstance(value, types.FunctionType)
        and value not in primitives
        and (value.__module__.startswith("ekfslam") or value.__module__ in modules)
    )


def called(fn: Callable, models: dict[str, object]) -> dict[str, object]:
    """The global names fn's code reads, with what they stand for (the models bound first).

    Only names loaded as globals: ``base.f`` reads the global ``base``, not a global ``f`` (a
    model calling another model's ``f`` from a module with an ``f`` of its own recursed
    without end when attribute names counted)."""
    names: dict[str, object] = {}
    codes = [fn.__code__]
    while codes:
        code = codes.pop()
        for instruction in dis.get_instructions(code):
            name = instruction.argval
            if instruction.opname not in _GLOBAL_LOADS:
                continue
            if name in models:
                names[name] = models[name]
            elif name in fn.__globals__:
                names[name] = fn.__globals__[name]
        codes += [c for c in code.co_consts if isinstance(c, types.CodeType)]
    return names


_GLOBAL_LOADS = frozenset({"LOAD_GLOBAL", "LOAD_NAME"})


def interpreted(fn: Callable, env: dict) -> Callable:
    """fn with the globals `env`, run by the interpreter (a `rebind` build)."""
    return types.FunctionType(fn.__code__, env, fn.__name__, fn.__defaults__, fn.__closure__)


def named(models: dict[str, object]) -> str:
    """``motion 'arc', sensor 'range-bearing'``: the models, as messages name them."""
    return ", ".join(f"{k} {getattr(m, 'name', m)!r}" for k, m in models.items())


def _model_functions(model: object) -> dict[str, Callable]:
    return {k: v for k, v in vars(model).items() if isinstance(v, types.FunctionType)}


def closure(
    roots: Iterable[Callable], models: dict[str, object], primitives: frozenset = frozenset()
) -> list[Callable]:
    """Every function the roots reach through their globals and the models, in a stable order."""
    modules = _model_modules(models)
    seen: dict[Callable, None] = {}
    todo = list(roots)
    while todo:
        fn = todo.pop(0)
        if fn in seen:
            continue
        seen[fn] = None
        for name, value in called(fn, models).items():
            if name in models:
                todo += list(_model_functions(value).values())
            elif _ours(value, modules, primitives):
                todo.append(value)
        for cell in fn.__closure__ or ():  # a factory's helpers, closed over like its parameters
            if _ours(cell.cell_contents, modules, primitives):
                todo.append(cell.cell_contents)
    return list(seen)


def rebind(
    roots: dict[str, Callable],
    models: dict[str, object],
    build: Callable[[Callable, dict], Callable],
    primitives: frozenset = frozenset(),
    replace: dict[Callable, Callable] | None = None,
) -> types.SimpleNamespace:
    """Copies of the roots whose model names, and every function of ours they call, are bound
    again: `build(fn, env)` makes one function from its original and its new globals. `replace`
    gives some functions another to stand in for them (generated code, the compiled backend's)."""
    modules = _model_modules(models)
    made: dict[Callable, Callable] = {}
    replace = replace or {}
    # a function reached again while its copy is being made (recursion): its name in those
    # globals is set once the copy exists (globals are read when called, or compiled)
    making: dict[Callable, list[tuple[dict, str]]] = {}

    def bound(value: Callable, env: dict, name: str) -> Callable:
        if value in making:
            making[value].append((env, name))
            return value
        return make(value)

    def make(fn: Callable) -> Callable:
        if fn in made:
            return made[fn]
        if fn in replace:
            made[fn] = make(replace[fn])
            return made[fn]
        making[fn] = []
        env = dict(fn.__globals__)
        for name, value in called(fn, models).items():
            if name in models:
                space = types.ModuleType(name)  # numba reads a module's attributes, compiled
                for k, v in _model_functions(value).items():
                    setattr(space, k, bound(v, vars(space), k))
                env[name] = space
            elif _ours(value, modules, primitives):
                env[name] = bound(value, env, name)
        for name, cell in zip(fn.__code__.co_freevars, fn.__closure__ or (), strict=True):
            value = (
                cell.cell_contents
            )  # a model's parameters (or helpers), as its factory made them
            env[name] = bound(value, env, name) if _ours(value, modules, primitives) else value
        made[fn] = build(fn, env)
        for where, name in making.pop(fn):
            where[name] = made[fn]
        return made[fn]

    return types.SimpleNamespace(**{name: make(fn) for name, fn in roots.items()})
