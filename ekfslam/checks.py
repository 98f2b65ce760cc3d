"""What a public function is given, checked where it takes it: one error naming the argument.

The functions a notebook user calls (``ekfslam.read_run``, ``replay``, ``align``, the configs,
the filter, ...) call these validators first, so that a wrong argument ends in one of our errors
with a message a student can act on, not in an AttributeError or a numpy broadcast error from
deep inside. Each validator raises

- `WrongTypeError` (a TypeError) for a wrong type: a path where a run belongs, a dict for a
  `NoiseConfig`, a σ given as a string;
- `ConfigError` (a ValueError) for a wrong value: a 2x2 where a 3x3 covariance belongs, a point
  with 3 coordinates, NaN, a covariance that is not positive semi-definite, an unknown choice;

and returns the value as checked (a float, a float array, a `Path`), so the caller goes on with
exactly what was checked. `name` is how the message names the argument, with its function:
``"replay: start_covariance"`` gives ``replay: start_covariance must be a 3x3 covariance matrix
of shape (3, 3), got shape (2, 2)``. `field_types` (`ekfslam.fieldtypes`, numpy-free so that a
config is) checks a dataclass's fields against their annotations: one line in a config's
``__post_init__``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Collection, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ekfslam.errors import ConfigError, WrongTypeError
from ekfslam.fieldtypes import field_types as field_types  # one layer: checks.field_types too
from ekfslam.fieldtypes import is_real, is_whole, shown
from ekfslam.files import user_path
from ekfslam.plausibility import implausible_pose

Array = NDArray[np.float64]

#: numpy dtype kinds that are numbers (bool is not: True is no length)
_NUMBER_KINDS = "iuf"
#: arrays of float64 up to this many values are checked as Python floats (`array`)
_SMALL = 64


# --------------------------------------------------------------------------------- scalars
def instance(value: Any, kind: type | tuple[type, ...], name: str, hint: str = "") -> Any:
    """`value` itself, if it is an instance of `kind`; else `WrongTypeError`.

    hint : what to do instead, appended after a colon (``read the folder first, ...``).
    """
    if isinstance(value, kind):
        return value
    kinds = kind if isinstance(kind, tuple) else (kind,)
    names = " or ".join(k.__name__ for k in kinds)
    got = "None" if value is None else shown(value)
    raise WrongTypeError(
        f"{name} must be {_article(names)}, got {got}" + (f": {hint}" if hint else "")
    )


def real(
    value: Any,
    name: str,
    *,
    lo: float | None = None,
    hi: float | None = None,
    lo_open: bool = False,
    unit: str = "",
) -> float:
    """A finite real number in [lo, hi] ((lo, hi] with `lo_open`), as a float.

    A string, a bool, None or an array is a `WrongTypeError`; NaN, inf or a value out of range
    a `ConfigError`.
    """
    if not is_real(value):
        raise WrongTypeError(f"{name} must be a number{_unit(unit)}, got {shown(value)}")
    try:
        x = float(value)
    except OverflowError:  # an integer of hundreds of digits
        raise ConfigError(f"{name} is a number too large for a float{_unit(unit)}") from None
    if not math.isfinite(x):
        raise ConfigError(f"{name} must be a finite number{_unit(unit)}, got {x!r}")
    if lo is not None and (x <= lo if lo_open else x < lo):
        raise ConfigError(
            f"{name} must be {'>' if lo_open else '>='} {lo:g}{_unit(unit)}, got {x!r}"
        )
    if hi is not None and x > hi:
        raise ConfigError(f"{name} must be at most {hi:g}{_unit(unit)}, got {x!r}")
    return x


def sigma(value: Any, name: str, unit: str = "") -> float:
    """A standard deviation: a finite number >= 0 (`real`)."""
    return real(value, name, lo=0.0, unit=unit)


def whole(value: Any, name: str, *, lo: int | None = None, hi: int | None = None) -> int:
    """A whole number (int or numpy integer) in [lo, hi], as an int."""
    if not is_whole(value):
        raise WrongTypeError(f"{name} must be a whole number, got {shown(value)}")
    n = int(value)
    if (lo is not None and n < lo) or (hi is not None and n > hi):
        span = (
            f"from {lo} to {hi}"
            if lo is not None and hi is not None
            else (f">= {lo}" if lo is not None else f"<= {hi}")
        )
        raise ConfigError(f"{name} must be a whole number {span}, got {n}")
    return n


def flag(value: Any, name: str) -> bool:
    """True or False (a numpy bool too); not a truthy string such as "no"."""
    if not isinstance(value, bool | np.bool_):
        raise WrongTypeError(f"{name} must be True or False, got {shown(value)}")
    return bool(value)


def choice(value: Any, name: str, choices: Collection[Any]) -> Any:
    """`value`, if it is one of `choices`; else a `ConfigError` listing them.

    An unknown choice never falls back to a default: ``method="meanDistance"`` is refused, not
    read as "no alignment".
    """
    listed = ", ".join(repr(c) for c in choices)
    # by type and value: an array compared with a string gives an array, 1 == True
    ok = any(type(value) is type(c) and value == c for c in choices)
    if not ok:
        kinds = {type(c) for c in choices}
        error = ConfigError if type(value) in kinds else WrongTypeError
        raise error(f"{name} must be one of {listed}, got {shown(value)}")
    return value


def path(value: Any, name: str) -> Path:
    """A file-system path (str or os.PathLike), not empty, as a `Path`.

    An empty string would mean the current folder (``Path("")`` is ``.``): refused, as bytes
    and None are.
    """
    if isinstance(value, bytes):
        raise WrongTypeError(f"{name} must be a path as text (str or pathlib.Path), got bytes")
    if not isinstance(value, str | os.PathLike):
        got = "None" if value is None else shown(value)
        raise WrongTypeError(f"{name} must be a path (str or pathlib.Path), got {got}")
    text = os.fspath(value)
    if isinstance(text, bytes):
        raise WrongTypeError(f"{name} must be a path as text (str or pathlib.Path), got bytes")
    if not text.strip():
        raise ConfigError(f"{name} is an empty path {text!r}; name a file or folder")
    if "\0" in text:
        raise ConfigError(f"{name} holds a NUL character, which no path can: {text!r}")
    return user_path(text)


# ---------------------------------------------------------------------------------- arrays
def array(
    value: Any,
    name: str,
    shape: tuple[int | None, ...],
    what: str = "",
    *,
    finite: bool = True,
    bound: float | None = None,
) -> Array:
    """`value` as a float array of `shape` (None: any length), finite unless told otherwise.

    what : what the array is, for the message (``"a pose (x, y, theta)"``).
    bound : the largest plausible magnitude of an entry (a position of 1e300 m is finite, but
        every product of it overflows).
    Strings, None, dicts and mixed objects are a `WrongTypeError`; a wrong shape, a ragged list,
    NaN/inf or an entry beyond `bound` a `ConfigError`.
    """
    try:
        a = np.asarray(value)
    except (ValueError, TypeError):  # a ragged list
        raise ConfigError(
            f"{name} must be {what or 'an array'} of shape {_shape_text(shape)}, got a ragged "
            f"list {shown(value)}"
        ) from None
    if a.dtype.kind not in _NUMBER_KINDS:
        if a.dtype.kind == "O" and a.size and all(map(is_real, a.flat)):
            try:
                a = a.astype(np.float64)
            except OverflowError:  # an integer of hundreds of digits
                raise ConfigError(f"{name} holds a number too large for a float") from None
        else:
            raise WrongTypeError(f"{name} must be {what or 'numbers'}, got {shown(value)}")
    if a.ndim != len(shape) or (
        a.shape != shape
        and any(s is not None and s != n for s, n in zip(shape, a.shape, strict=False))
    ):
        raise ConfigError(f"{name} must be {what or 'an array'}{_shape_problem(shape, a.shape)}")
    out = a.astype(np.float64, copy=False)
    if out.size <= _SMALL and finite and _small_and_sound(out, bound):
        return out
    if finite and not np.isfinite(out).all():
        where = tuple(int(i) for i in np.argwhere(~np.isfinite(out))[0])
        at = f" at index {where[0] if len(where) == 1 else where}" if where else ""
        bad = out[where] if where else out
        raise ConfigError(f"{name} must be finite numbers, got a non-finite {float(bad)!r}{at}")
    if bound is not None and out.size and float(np.abs(out).max()) > bound:
        where = tuple(int(i) for i in np.argwhere(np.abs(out) > bound)[0])
        at = f" at index {where[0] if len(where) == 1 else where}" if where else ""
        raise ConfigError(
            f"{name}: {float(out[where] if where else out)!r}{at} is not plausible (beyond "
            f"±{bound:g})"
        )
    return out


def _small_and_sound(a: Array, bound: float | None) -> bool:
    """Are a small array's values finite and within ±bound? As Python floats: a user's loop
    checks a z or a u per call, and 0.5 µs here is 3 µs in numpy's reductions. A NaN or inf
    makes the sum non-finite; a sum that overflowed says False, and `array`'s precise check
    then decides (and names the entry)."""
    flat = a.ravel().tolist()
    if not math.isfinite(sum(flat)):
        return False
    return bound is None or not flat or -bound <= min(flat) <= max(flat) <= bound


def vector(value: Any, name: str, n: int, what: str = "") -> Array:
    """A finite float vector of length n (`array`)."""
    return array(value, name, (n,), what or f"{n} numbers")


def pose(value: Any, name: str) -> Array:
    """A pose (x, y, θ) in m, m, rad: 3 finite numbers, |x|, |y| <= 1e7 m, |θ| <= 2π."""
    p = vector(value, name, 3, "a pose (x, y, theta) in m, m, rad")
    problem = implausible_pose(p, name)
    if problem is not None:
        raise ConfigError(problem)
    return p


def point(value: Any, name: str) -> Array:
    """A point (x, y) in m: 2 finite numbers within 1e7 m."""
    p = vector(value, name, 2, "a point (x, y) in m")
    problem = implausible_pose(p, name, pose=False)
    if problem is not None:
        raise ConfigError(problem)
    return p


def rows(value: Any, name: str, width: int, what: str = "", bound: float | None = None) -> Array:
    """Rows of `width` finite numbers: (width,) or (N, width) (`array`), within ±`bound`."""
    try:
        ndim = np.ndim(value)
    except (ValueError, TypeError):  # ragged: `array` says so
        ndim = 2
    shape: tuple[int | None, ...] = (width,) if ndim == 1 else (None, width)
    return array(value, name, shape, what or f"rows of {width} numbers", bound=bound)


def covariance(value: Any, name: str, n: int, *, definite: bool = False, what: str = "") -> Array:
    """A covariance matrix (n, n): finite, symmetric, positive semi-definite (or definite).

    Symmetric to 1e-9 of its largest entry; semi-definite when no eigenvalue is below -1e-12 of
    the largest (rounding), definite when every eigenvalue is above that. A negative-definite
    start covariance otherwise returns a confident map metres off.
    """
    label = what or f"a {n}x{n} covariance matrix"
    a = array(value, name, (n, n), label)
    scale = float(np.abs(a).max()) if a.size else 0.0
    asym = float(np.abs(a - a.T).max()) if a.size else 0.0
    if asym > 1e-9 * scale:
        raise ConfigError(
            f"{name} must be symmetric ({label}); it differs from its transpose by {asym:.3g}"
        )
    eig = np.linalg.eigvalsh(0.5 * (a + a.T))
    floor = 1e-12 * max(float(np.abs(eig).max()), 0.0)
    if definite and not eig[0] > floor:
        raise ConfigError(
            f"{name} must be positive definite ({label}, every variance > 0); its smallest "
            f"eigenvalue is {eig[0]:.3g}"
        )
    if eig[0] < -floor:
        raise ConfigError(
            f"{name} must be positive semi-definite ({label}: variances >= 0); its smallest "
            f"eigenvalue is {eig[0]:.3g} (a sign error?)"
        )
    return a


def points_by_id(value: Any, name: str) -> dict[int, Array]:
    """A map {landmark id: (x, y)}: a mapping with integer ids and 2 finite numbers each."""
    if not isinstance(value, Mapping) and not hasattr(value, "items"):
        raise WrongTypeError(
            f"{name} must be a mapping {{landmark id: (x, y)}}, got {shown(value)}"
        )
    out: dict[int, Array] = {}
    for key, xy in value.items():
        if not is_whole(key):
            raise ConfigError(f"{name}: landmark ids must be integers, got {shown(key)}")
        out[int(key)] = point(xy, f"{name}[{key}]")
    return out


# -------------------------------------------------------------------------------- plumbing
def _article(noun: str) -> str:
    return ("an " if noun[:1].lower() in "aeiou" else "a ") + noun


def _unit(unit: str) -> str:
    return f" ({unit})" if unit else ""


def _shape_problem(want: tuple[int | None, ...], got: tuple[int, ...]) -> str:
    """The end of a shape message: ": 3 numbers, got 2" or " of shape (3, 3), got shape (2, 2)"."""
    if len(want) == 1 and want[0] is not None and len(got) == 1:
        return f": {want[0]} numbers, got {got[0]}"
    return f" of shape {_shape_text(want)}, got shape {got}"


def _shape_text(shape: Iterable[int | None]) -> str:
    parts = ["N" if s is None else str(s) for s in shape]
    return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"
