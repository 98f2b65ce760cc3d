"""A dataclass's fields checked against their annotations: one line in a config's ``__post_init__``.

Part of the validation layer (`ekfslam.checks`), without numpy: `ekfslam.core.filter.config` uses
it, and the command line's ``--help`` must load no numeric library. numpy's scalars are told
apart through the `numbers` ABCs they register with (np.float32 is a `numbers.Real`, np.int64 a
`numbers.Integral`, np.bool_ neither).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import sys
import types
import typing
from collections.abc import Mapping
from typing import Any

from ekfslam.errors import ConfigError, WrongTypeError

_SHOWN = 60  # characters of a value's repr a message shows


def shown(value: object) -> str:
    """`value` as a message shows it: a clipped repr and its type (an array: shape and dtype)."""
    if hasattr(value, "shape") and hasattr(value, "dtype"):  # a numpy array (no numpy here)
        return f"an array of shape {value.shape} ({value.dtype})"
    text = repr(value)
    if len(text) > _SHOWN:
        text = text[: _SHOWN - 3] + "..."
    return f"{text} ({type(value).__name__})"


def is_real(value: object) -> bool:
    """Whether `value` is one real number: int, float or a numpy number, not a bool or a str."""
    return isinstance(value, numbers.Real) and not _is_bool(value)


def is_whole(value: object) -> bool:
    """Whether `value` is an int or a numpy integer (not a bool, not a float like 3.0)."""
    return isinstance(value, numbers.Integral) and not _is_bool(value)


def finite(value: object) -> bool:
    """Whether the real number `value` is finite as a float (an int of 400 digits is not)."""
    try:
        return math.isfinite(float(value))  # type: ignore[arg-type]
    except (OverflowError, TypeError, ValueError):
        return False


def _is_bool(value: object) -> bool:
    return isinstance(value, bool) or type(value).__name__ == "bool_"  # numpy's, unnamed here


_HINTS: dict[type, dict[str, Any]] = {}


def field_types(obj: Any) -> None:
    """Check every field of the dataclass `obj` against its annotation.

    float means a real number (an int too, not a bool or a str), int a whole number, bool True
    or False, str a string, ``Literal[...]`` one of its values, a class an instance of it,
    ``X | None`` either, ``tuple[...]`` a sequence whose items match; anything else (an array
    alias, ``Any``) is not checked here. A wrong type raises `WrongTypeError`, a value outside a
    ``Literal`` `ConfigError`, each naming ``Class.field``.
    """
    cls = type(obj)
    hints = _HINTS.get(cls)
    if hints is None:
        hints = _HINTS[cls] = _field_hints(cls)
    for field in dataclasses.fields(obj):
        hint = hints.get(field.name)
        if hint is None:
            continue
        value = getattr(obj, field.name)
        if not _matches(value, hint):
            name = f"{cls.__name__}.{field.name}"
            literals = _literals(hint)
            if literals and isinstance(value, str | int | float) and not isinstance(value, bool):
                listed = ", ".join(repr(v) for v in literals + ((None,) if _optional(hint) else ()))
                raise ConfigError(f"{name} must be one of {listed}, got {shown(value)}")
            length = _length_problem(value, hint)
            if length is not None:
                raise ConfigError(f"{name} must be {length}")
            raise WrongTypeError(f"{name} must be {_describe(hint)}, got {shown(value)}")


def _field_hints(cls: type) -> dict[str, Any]:
    """Each field's annotation, evaluated; a field whose annotation does not evaluate (a type
    imported only for type checking) is left out."""
    module = sys.modules.get(cls.__module__)
    space = {**vars(typing), **(vars(module) if module else {})}
    hints = {}
    for field in dataclasses.fields(cls):
        hint = field.type
        if isinstance(hint, str):
            try:
                hint = eval(hint, space)  # our own annotation text, never user input
            except Exception:
                continue
        hints[field.name] = hint
    return hints


def _union_args(hint: Any) -> tuple[Any, ...] | None:
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return typing.get_args(hint)
    return None


def _optional(hint: Any) -> bool:
    arms = _union_args(hint)
    return arms is not None and type(None) in arms


def _literals(hint: Any) -> tuple[Any, ...]:
    arms = _union_args(hint) or (hint,)
    return tuple(
        v for arm in arms if typing.get_origin(arm) is typing.Literal for v in typing.get_args(arm)
    )


def _matches(value: Any, hint: Any) -> bool:
    if hint is Any or hint is object:
        return True
    if hint is type(None) or hint is None:
        return value is None
    arms = _union_args(hint)
    if arms is not None:
        return any(_matches(value, arm) for arm in arms)
    origin = typing.get_origin(hint)
    if origin is typing.Literal:
        return any(type(value) is type(v) and value == v for v in typing.get_args(hint))
    if hint is float:
        return is_real(value)
    if hint is int:
        return is_whole(value)
    if hint is bool:
        return _is_bool(value)
    if hint is str:
        return isinstance(value, str)
    if origin is tuple:
        items = _items(value)
        if items is None:
            return False
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_matches(v, args[0]) for v in items)
        return len(args) == len(items) and all(
            _matches(v, a) for v, a in zip(items, args, strict=True)
        )
    if origin is dict or hint is dict:
        if not isinstance(value, Mapping):
            return False
        args = typing.get_args(hint)
        return not args or all(_matches(k, args[0]) for k in value)
    if isinstance(hint, type) and origin is None:
        return isinstance(value, hint)
    return True  # an array alias or another generic: checked by the class itself


def _items(value: Any) -> list | None:
    """The items of a tuple, list or array (nested arrays as lists), else None."""
    if isinstance(value, tuple | list):
        return list(value)
    if hasattr(value, "tolist") and hasattr(value, "shape") and len(value.shape) >= 1:
        return value.tolist()
    return None


def _length_problem(value: Any, hint: Any) -> str | None:
    """A sequence of the right kind of items but the wrong count, for a fixed-length tuple."""
    for arm in _union_args(hint) or (hint,):
        args = typing.get_args(arm)
        items = _items(value)
        if typing.get_origin(arm) is not tuple or items is None or Ellipsis in args:
            continue
        if len(items) != len(args) and all(_matches(v, args[0]) for v in items):
            return f"{len(args)} {_plural(args[0])}, got {len(items)}: {shown(value)}"
    return None


def _describe(hint: Any) -> str:
    arms = _union_args(hint)
    if arms is not None:
        return " or ".join(_describe(a) for a in arms)
    if hint is type(None):
        return "None"
    origin = typing.get_origin(hint)
    if origin is typing.Literal:
        return "one of " + ", ".join(repr(v) for v in typing.get_args(hint))
    named = {float: "a number", int: "a whole number", bool: "True or False", str: "a string"}
    if hint in named:
        return named[hint]
    if origin is tuple:
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return "a tuple of " + _plural(args[0])
        return f"a tuple of {len(args)} " + _plural(args[0] if args else float)
    if origin is dict or hint is dict:
        return "a dict"
    return _article(getattr(hint, "__name__", str(hint)))


def _plural(hint: Any) -> str:
    return {float: "numbers", int: "whole numbers", str: "strings"}.get(
        hint, "values" if typing.get_origin(hint) is not tuple else "tuples"
    )


def _article(noun: str) -> str:
    return ("an " if noun[:1].lower() in "aeiou" else "a ") + noun
