"""The student's side of grading one exercise, run inside the sandbox of `ekfslam.cli.lab_sandbox`:
``python -m ekfslam.cli.lab_producer IN OUT`` (frames on the file descriptors IN and OUT).

It only produces. It runs the student's notebook, as the student's own code, up to the check cell
of the exercise being graded (every code cell before it, in order, an error in one not stopping
the next; outputs discarded), then answers the grader's requests: call the exercise's function
on these inputs (`ekfslam.teaching.lab_wire` values) and send back what it returned, what it
raised, and which input it changed. It holds no key and no expected value, computes no score,
and writes nowhere but its own private folder: whatever a submission does to this process can
change only what its own function is seen to return.

The package it imports is the sandbox's: the exercise's own implementation and everything that
does the same work left out (`ekfslam.errors.Forbidden`), the lab's checks answering yes without
judging (the grader judges, outside).
"""

from __future__ import annotations

import contextlib
import copy
import io
import json
import os
import resource
import sys
import warnings

import numpy as np

from ekfslam.teaching.lab_wire import WireError, decode, encode, read_frame, write_frame

MAX_MESSAGE = 300


def code_cells(notebook: dict, stop_at: str) -> list[str]:
    """The sources of the code cells before the check cell whose grade id is `stop_at` (all of
    them when the student's notebook has no such cell)."""
    sources = []
    for cell in notebook.get("cells", []):
        if not isinstance(cell, dict):
            continue
        meta = (
            cell.get("metadata", {}).get("nbgrader", {})
            if isinstance(cell.get("metadata"), dict)
            else {}
        )
        if isinstance(meta, dict) and meta.get("grade") and meta.get("grade_id") == stop_at:
            break
        if cell.get("cell_type") == "code":
            source = cell.get("source", "")
            sources.append("".join(source) if isinstance(source, list) else str(source))
    return sources


def run_notebook(sources: list[str]) -> tuple[dict, list[str]]:
    """Run the cells in one IPython shell; (its namespace, a line per cell that raised)."""
    from IPython.core.interactiveshell import InteractiveShell  # lazy: the sandbox's only use

    class Shell(InteractiveShell):
        """A notebook's kernel without a screen: ``%matplotlib`` draws off screen."""

        def enable_gui(self, gui=None):  # type: ignore[no-untyped-def]
            return None

        def enable_matplotlib(self, gui=None):  # type: ignore[no-untyped-def]
            return "agg", "agg"  # MPLBACKEND is Agg

    shell = Shell.instance()
    errors = []
    for i, source in enumerate(sources):
        with _quiet():
            result = shell.run_cell(source, store_history=False, silent=True)
        error = result.error_before_exec or result.error_in_exec
        if error is not None:
            errors.append(f"code cell {i + 1} raised {_describe(error)}")
    return shell.user_ns, errors


@contextlib.contextmanager
def _quiet():
    with (
        contextlib.redirect_stdout(io.StringIO()),
        contextlib.redirect_stderr(io.StringIO()),
        warnings.catch_warnings(),
    ):
        warnings.simplefilter("ignore")
        yield


def _describe(error: BaseException) -> str:
    return f"{type(error).__name__}: {error}"[:MAX_MESSAGE]


class _Watched:
    """A notebook function counted as the answer calls it (6b's `joseph`)."""

    def __init__(self, fn):
        self.fn, self.calls = fn, 0

    def __call__(self, *args, **kwargs):
        self.calls += 1
        return self.fn(*args, **kwargs)


def _same(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.shape(a) == np.shape(b) and bool(np.array_equal(a, b, equal_nan=True))
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if hasattr(a, "__dataclass_fields__") and type(a) is type(b):
        return all(_same(getattr(a, f), getattr(b, f)) for f in a.__dataclass_fields__)
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return True


def call(fn, args: list) -> dict:
    """`fn(*args)` on copies of `args`: its result, or what it raised; the inputs it changed;
    for an input that is driven (exercise 8's filter) the driven thing's state afterwards."""
    driven = [i for i, a in enumerate(args) if hasattr(a, "build") and hasattr(a, "snapshot")]
    given = [copy.deepcopy(a) for a in args]
    built = {i: args[i].build() for i in driven}
    for i, thing in built.items():
        given[i] = thing
    try:
        with _quiet():
            result = fn(*given)
            if driven:
                result = args[driven[0]].snapshot(built[driven[0]])
            answer = {"result": encode(result)}
    except BaseException as error:  # the student's: any of it, even SystemExit
        answer = {
            "raised": type(error).__name__,
            "forbidden": type(error).__name__ == "LabForbidden",
            "message": str(error)[:MAX_MESSAGE],
        }
    answer["mutated"] = [
        i for i in range(len(args)) if i not in built and not _same(args[i], given[i])
    ]
    return answer


def _cpu_seconds() -> float:
    """This process's CPU time and its finished children's: what the grading of one exercise
    cost (the sandbox's PID namespace hides it from the grader's own accounting)."""
    me, children = (
        resource.getrusage(resource.RUSAGE_SELF),
        resource.getrusage(resource.RUSAGE_CHILDREN),
    )
    return me.ru_utime + me.ru_stime + children.ru_utime + children.ru_stime


def serve(setup: dict, REQUESTS: int, ANSWERS: int) -> None:
    with open(setup["notebook"], encoding="utf-8") as f:
        try:
            notebook = json.load(f)
        except ValueError as error:
            write_frame(ANSWERS, {"ready": False, "why": f"not a notebook ({error})"[:200]})
            return
    namespace, errors = run_notebook(code_cells(notebook, setup["stop_at"]))
    fn = namespace.get(setup["function"])
    write_frame(ANSWERS, {"ready": True, "defined": callable(fn), "errors": errors[:20]})
    watched = None
    while True:
        try:
            request = read_frame(REQUESTS)
        except WireError:
            return
        if not isinstance(request, dict) or request.get("bye"):
            write_frame(ANSWERS, {"cpu": _cpu_seconds()})  # for the grader's timings only
            return
        if "watch" in request:
            target = namespace.get(str(request["watch"]))
            watched = _Watched(target) if callable(target) else None
            if watched is not None:
                namespace[str(request["watch"])] = watched
            write_frame(ANSWERS, {"watching": watched is not None})
        elif "watched" in request:
            write_frame(ANSWERS, {"calls": watched.calls if watched else None})
        else:
            try:
                args = decode(request.get("call"), dataclasses_allowed=True)
            except (WireError, ImportError, AttributeError) as error:
                write_frame(ANSWERS, {"raised": "WireError", "message": str(error)[:200]})
                continue
            write_frame(ANSWERS, call(fn, list(args)))


def main(argv: list[str]) -> int:
    os.environ.setdefault("MPLBACKEND", "Agg")
    requests, answers = int(argv[0]), int(argv[1])
    try:
        setup = read_frame(requests)
    except WireError:
        return 2
    serve(setup, requests, answers)
    os._exit(0)  # nothing of the notebook's to tear down: the sandbox is discarded whole


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
