"""ekfslam's own exception types: each message is one line a student can act on.

The hierarchy (``docs/guide/errors.md`` shows each with an example)::

    EkfSlamError                        every error ekfslam raises on purpose
    ├── InputError (ValueError)         bad data in a file: names the file, the line, the problem
    ├── OutputError (OSError)           a result cannot be written where the user asked
    ├── ConfigError (ValueError)        a setting, option or argument with a bad value
    │   └── WrongTypeError (TypeError)  an argument of the wrong type (a str for a σ)
    └── AlignmentError (ValueError)     the map cannot be aligned (eq. 17)

`LabForbidden` (an ImportError) is what a graded sandbox of the lab raises where the package's
own implementation of an exercise was: `Forbidden` stands for each such name.

So ``except ValueError`` catches every bad input, setting or argument, and ``except OSError``
every failed write, as for Python's own errors.

`Interrupted` is not an error: a signal (Ctrl-C, SIGTERM) ended a command on the command line.
"""

from __future__ import annotations

import signal

#: The most characters of a problem a message repeats (the file and line come before it).
MAX_PROBLEM = 400
#: The most characters of any message of ours.
MAX_MESSAGE = 600


class EkfSlamError(Exception):
    """Base class of every error ekfslam raises on purpose.

    Its message is one line of at most `MAX_MESSAGE` characters (`one_line`), whatever value it
    repeats: a 5,000-digit number or a whole RunLog's repr is not echoed whole.
    """

    def __init__(self, *args: object) -> None:
        if args and isinstance(args[0], str):
            args = (one_line(args[0], MAX_MESSAGE), *args[1:])
        super().__init__(*args)


class InputError(EkfSlamError, ValueError):
    """Bad input data. The message names the file, the line (when there is one) and the problem.

    Example: ``controls.csv:57: time 12.40 s is earlier than the previous row (12.45 s)``. A
    ValueError too (bad data is a bad value), so ``except ValueError`` catches it.
    """

    def __init__(self, path: object, line: int | None, problem: str) -> None:
        self.path = str(path)
        self.line = line
        self.problem = one_line(problem)
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {self.problem}")

    def __reduce__(self) -> tuple:  # across processes (a study's --jobs): its own three fields
        return type(self), (self.path, self.line, self.problem)


class OutputError(EkfSlamError, OSError):
    """A result cannot be written to the path the user gave; the message names that path.

    Example: ``/proc/fig.png: cannot write here (No such file or directory); choose another
    path``. Raised before the work when the target is probed (`ekfslam.files.probe_output`), and
    for any OSError while writing (`ekfslam.files.atomic_write`), never naming a temporary file.
    An OSError too, as the failure it reports is.
    """

    def __init__(self, path: object, problem: str) -> None:
        super().__init__(f"{path}: {problem}")
        self.path = str(path)
        self.problem = one_line(problem)

    def __str__(self) -> str:  # OSError's own would add nothing, but say it plainly
        return f"{self.path}: {self.problem}"

    def __reduce__(self) -> tuple:  # across processes: OSError's own pickles its errno fields
        return type(self), (self.path, self.problem)


def one_line(text: str, limit: int = MAX_PROBLEM) -> str:
    """`text` on one line (runs of white space, newlines too, as one space), clipped to `limit`
    characters: a library's multi-line message, or a 20 MB cell, is not echoed whole."""
    text = " ".join(str(text).split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


class AlignmentError(EkfSlamError, ValueError):
    """The map cannot be aligned (fewer than two landmarks in common, all at one point, ...).

    A ValueError too, so ``except ValueError`` around an alignment keeps working.
    """


class ConfigError(EkfSlamError, ValueError):
    """A value out of its range: an option, a config field or a function's argument
    (``gate must be > 0``, ``replay: start_covariance must be a 3x3 matrix, got shape (2, 2)``).

    A ValueError too, so callers (and tests) that caught the ValueError the config dataclasses
    raised before this type existed keep working.
    """


class WrongTypeError(ConfigError, TypeError):
    """A function was given an argument of the wrong type; the message names the argument, what
    it must be and how to make one (``replay: run must be a RunLog, got 'runs/x' (str): read the
    folder first, ekfslam.read_run(folder)``).

    A TypeError, as Python's own are, and a `ConfigError` (so a ValueError) too: ``except
    ValueError`` around a call still catches every bad argument, of whichever kind.
    """


class LabForbidden(ImportError):
    """The package's implementation of a lab exercise, called while that exercise is graded:
    the sandbox holds a stand-in that raises this (`ekfslam.cli.lab_sandbox` writes it)."""


class Forbidden:
    """A stand-in for a name of the package that a graded sandbox leaves out: importing it
    works, so a notebook's other cells still run; calling it, or anything reached through it,
    raises `LabForbidden` naming it."""

    def __init__(self, name: str, exercise: str) -> None:
        self._name, self._exercise = name, exercise

    def __call__(self, *args: object, **kwargs: object) -> object:
        raise LabForbidden(
            f"the package's {self._name} is not available while exercise {self._exercise} is "
            "graded: write it yourself"
        )

    def __getattr__(self, attr: str) -> Forbidden:
        if attr.startswith("__"):
            raise AttributeError(attr)
        return Forbidden(f"{self._name}.{attr}", self._exercise)

    def __mro_entries__(self, bases: tuple) -> tuple:
        self()  # a class derived from a left-out class is a use of it
        return ()

    def __repr__(self) -> str:
        return f"<{self._name}: left out while exercise {self._exercise} is graded>"


class Interrupted(KeyboardInterrupt):
    """A signal ended a command: Ctrl-C (SIGINT) or SIGTERM. `signum` says which.

    A KeyboardInterrupt, so that nothing catching ``Exception`` swallows it and every
    ``finally`` (and `ekfslam.files.atomic_write`'s clean-up) runs on the way out. The command
    line ends with one line and exit status 128 + `signum` (130 for Ctrl-C, 143 for SIGTERM).
    """

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(signal.Signals(signum).name)

    def __reduce__(self) -> tuple:
        return type(self), (self.signum,)
