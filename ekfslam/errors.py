"""ekfslam's own exception types: each message is one line a student can act on."""

from __future__ import annotations


class EkfSlamError(Exception):
    """Base class of every error ekfslam raises on purpose."""


class InputError(EkfSlamError):
    """Bad input data. The message names the file, the line (when there is one) and the problem.

    Example: ``controls.csv:57: time 12.40 s is earlier than the previous row (12.45 s)``.
    """

    def __init__(self, path: object, line: int | None, problem: str) -> None:
        self.path = str(path)
        self.line = line
        self.problem = problem
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")


class AlignmentError(EkfSlamError):
    """The map cannot be aligned (for example, fewer than two landmarks in common)."""


class ConfigError(EkfSlamError, ValueError):
    """A setting out of its range: a bad option value or config field (``gate must be > 0``).

    A ValueError too, so callers (and tests) that caught the ValueError the config dataclasses
    raised before this type existed keep working.
    """
