"""The lab's tripwire: while a student's function runs, any call into ekfslam's own code that the
exercise does not allow is noted, so that a check can say "you called the package's
predict_step: write it yourself" and score the exercise 0.

It does not know the package's function names: a profile hook (`sys.setprofile`), on only while
the student's function runs, sees every Python call (and every call of a numba-compiled function,
whose dispatcher reports its Python function to an active profiler) and looks at the file the
called code lives in. A call is the student's own when it crosses into the package from outside
it: no frame of the package lies between the student's function and the call. Such a call is
allowed only when its code is on the exercise's short allowlist (say `wrap_angle` where the
exercise is not the wrap, or the filter's methods in the replay loop); what an allowed function
does inside is its own business. Renaming, aliasing, `functools.partial`, calling through numpy
or scipy, or through any other function of the package: the call still enters a file of the
package, so it is still seen. Importing (a module's body, the package's lazy `__getattr__`) is
not a call of the package's work and is let through.

What it cannot see is code copied out of the package's files into the notebook: that is the
student's code then, as any code read in a book.
"""

from __future__ import annotations

import inspect
import sys
import types
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

PACKAGE = str(Path(__file__).resolve().parents[1]) + "/"  # ekfslam/, with the separator
SYMPY_DIFFERENTIATION = ("jacobian", "diff")  # sympy's code that derives: exercise 2a, 4a


def in_package(filename: str) -> bool:
    """True for a file of ekfslam's own source."""
    return filename.startswith(PACKAGE)


def code_objects(allowed: Iterable[object]) -> frozenset[types.CodeType | str]:
    """The code objects of functions, methods, properties, numba dispatchers and classes (all
    their methods, their bases' too); for a module, its file (every function defined in it)."""
    found: set[types.CodeType | str] = set()

    def add(thing: object) -> None:
        if isinstance(thing, types.FunctionType):
            found.add(thing.__code__)
        elif isinstance(thing, staticmethod | classmethod):
            add(thing.__func__)
        elif isinstance(thing, property):
            for f in (thing.fget, thing.fset, thing.fdel):
                add(f)
        elif isinstance(thing, type):
            for klass in thing.__mro__:
                for value in vars(klass).values():
                    add(value)
        elif isinstance(thing, types.ModuleType) and getattr(thing, "__file__", None):
            found.add(str(Path(thing.__file__).resolve()))
        elif hasattr(thing, "py_func"):  # a numba dispatcher: its Python function
            add(thing.py_func)
        elif isinstance(thing, types.MethodType):
            add(thing.__func__)

    for thing in allowed:
        add(thing)
    return frozenset(found)


def _is_import(code: types.CodeType) -> bool:
    """A module's body, or a package's lazy attribute loader (PEP 562)."""
    return code.co_name == "<module>" or (
        code.co_name == "__getattr__" and code.co_filename.endswith("__init__.py")
    )


@dataclass
class Watch:
    """What the hook saw: the package's code the student's function called without leave (the
    first one's name is the verdict), and whether sympy differentiated."""

    allowed: frozenset[types.CodeType | str]
    entry: types.FrameType | None = None
    forbidden: list[str] = field(default_factory=list)
    differentiated: bool = False

    def crossing(self, back: types.FrameType | None) -> bool:
        """True when a call made from frame `back` enters the package from outside it (no
        package frame between `back` and the student's function)."""
        while back is not None and back is not self.entry:
            if in_package(back.f_code.co_filename):
                return False
            back = back.f_back
        return True

    def profile(self, frame: types.FrameType, event: str, arg: object) -> None:
        if event != "call":
            return
        code = frame.f_code
        if code.co_name in SYMPY_DIFFERENTIATION and "sympy" in code.co_filename:
            self.differentiated = True
        if not in_package(code.co_filename) or _is_import(code):
            return
        if code in self.allowed or code.co_filename in self.allowed:
            return
        # a numba-compiled function's frame is made for the profiler, unlinked: its caller is the
        # frame running when the hook is called
        caller = frame.f_back if frame.f_back is not None else sys._getframe(1)
        if self.forbidden or not self.crossing(caller):
            return
        # a callable standing for a compiled function (the compiled backend's first call)
        # is named by that function, not by its __call__
        stands_for = getattr(frame.f_locals.get("self"), "py_func", None)
        code = getattr(stands_for, "__code__", code)
        self.forbidden.append(getattr(code, "co_qualname", code.co_name))


def clear_package_caches() -> None:
    """Empty every `functools.cache` of the package: a cached call runs no Python code, so the
    hook would not see the student's call of a function the package had called before."""
    for name, module in list(sys.modules.items()):
        if not name.startswith("ekfslam") or module is None:
            continue
        for value in list(vars(module).values()):
            wrapped = getattr(value, "__wrapped__", None)
            code = getattr(wrapped, "__code__", None)
            if code is not None and hasattr(value, "cache_clear") and in_package(code.co_filename):
                value.cache_clear()


def call_watched(
    fn: Callable, args: tuple, allowed: frozenset[types.CodeType | str]
) -> tuple[object, Watch]:
    """`fn(*args)` with the tripwire on; (its result, what the hook saw). Exceptions pass."""
    clear_package_caches()
    watch = Watch(allowed, entry=sys._getframe())  # this frame marks the student's side
    previous = sys.getprofile()
    sys.setprofile(watch.profile)
    try:
        result = fn(*args)
    finally:
        sys.setprofile(previous)
    return result, watch


def describe(fn: object) -> str:
    """`fn`'s name as a student wrote it (for a verdict)."""
    return getattr(fn, "__name__", None) or type(fn).__name__


def source_file(fn: object) -> str | None:
    """The file `fn` was defined in, or None."""
    try:
        return inspect.getsourcefile(fn)  # type: ignore[arg-type]
    except TypeError:
        return None
