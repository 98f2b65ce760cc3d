"""What the command line accepts: the parser, option types with their ranges, shared options.

Every bad option value is refused while the command line is parsed, before any work, with ONE
line on stderr and exit status 2::

    python -m ekfslam run: error: argument --sigma-range: must be > 0, got 0 (see ... --help)

Output paths (``--plot``, ``--out``, ``--animate``) are checked the same way: the format is
known and the target is probed (`ekfslam.files.output_problem`: not empty, no name too long, not a
folder where a file belongs, only folders on the way, a folder that takes a new file). Missing
parent folders are created when the file is written, and every file is written to a temporary
file beside it and renamed into place (`atomic_write`), so a failed or interrupted write never
leaves half a file and keeps the old one (`ekfslam.files`).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, NoReturn

from ekfslam.core.filter.config import CHI2_2DOF_99, LINEARIZATIONS
from ekfslam.files import not_a_file, output_problem, user_path

#: What ``--plot`` writes (matplotlib infers the format from the suffix; these need no extras).
PLOT_FORMATS: tuple[str, ...] = (".png", ".pdf", ".svg")
#: Upper bounds of the noise options: beyond them σ² dt, and Σ, lose every digit of the poses.
MAX_MOTION_SIGMA = 10.0  # m/√s and rad/√s
MAX_RANGE_SIGMA = 100.0  # m
#: MRCLAM's robots, the values of ``--robot``.
ROBOTS = range(1, 6)
#: MRCLAM's nine datasets; a command names one by its folder or by its number
MRCLAM_DATASETS = range(1, 10)

Check = Callable[[argparse.Namespace], str | None]


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line, and which runs cross-option checks.

    `add_check(fn)` registers ``fn(namespace) -> message or None``; a message is an error, in
    the same one-line form as argparse's own (start it with ``argument --opt:``).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._checks: list[Check] = []

    def add_check(self, check: Check) -> None:
        self._checks.append(check)

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[no-untyped-def]
        words = list(sys.argv[1:] if args is None else args)
        namespace, extras = super().parse_known_args(words, namespace)
        conflict = self._conflict(words)
        if conflict is not None:
            self.error(conflict)
        for check in self._checks:
            problem = check(namespace)
            if problem is not None:
                self.error(problem)
        return namespace, extras

    def _conflict(self, words: list[str]) -> str | None:
        """An option given twice with different values, or ``--X`` beside ``--no-X``: argparse
        would keep the last one silently; we say so instead. Repeating an option with the same
        value is harmless; options that collect (append, count) may repeat."""
        given: dict[str, tuple[str, tuple[str, ...]]] = {}  # dest -> (as typed, values)
        typed: dict[str, str] = {}  # every full option string given -> as typed
        for i, word in enumerate(words):
            if word == "--":
                break
            if not word.startswith("--"):
                continue
            head, eq, value = word.partition("=")
            action = self._option_action(head)
            if action is None or isinstance(action, _REPEATABLE):
                continue
            full = next(o for o in action.option_strings if o.startswith(head))
            typed[full] = head
            values = (value,) if eq else _values_after(words, i + 1, action.nargs)
            if action.dest in given and given[action.dest][1] != values:
                first, before = given[action.dest]
                shown = " and ".join(
                    f"{o} {' '.join(v)}".strip() for o, v in ((first, before), (head, values))
                )
                return f"argument {head}: given twice with different values ({shown}); give it once"
            given[action.dest] = (head, values)
        for full, head in typed.items():
            if full.startswith("--no-") and f"--{full[5:]}" in typed:
                return (
                    f"argument {head}: contradicts {typed[f'--{full[5:]}']}, given too; "
                    "give one of them"
                )
        return None

    def _option_action(self, head: str) -> argparse.Action | None:
        """The action `head` names: exactly, or as the unique abbreviation argparse accepts."""
        actions = self._option_string_actions
        if head in actions:
            return actions[head]
        if not self.allow_abbrev:
            return None
        found = {actions[o] for o in actions if o.startswith(head)}
        return found.pop() if len(found) == 1 else None

    def error(self, message: str) -> NoReturn:
        # argparse prints the whole usage first; one line that points at --help reads better
        one_line = " ".join(message.split())
        self.exit(2, f"{self.prog}: error: {one_line} (see {self.prog} --help)\n")


#: Options that collect their values and so may be given more than once.
_REPEATABLE = (
    argparse._AppendAction,
    argparse._AppendConstAction,
    argparse._CountAction,
    argparse._ExtendAction,
    argparse._HelpAction,
    argparse._VersionAction,
)
_NUMBER = re.compile(r"-\d+(\.\d*)?([eE][+-]?\d+)?|-\.\d+|-inf|-nan", re.IGNORECASE)


def _values_after(words: list[str], start: int, nargs: int | str | None) -> tuple[str, ...]:
    """The words an option with `nargs` takes after it (a negative number is a value)."""
    if nargs == 0:
        return ()
    if isinstance(nargs, int):
        return tuple(words[start : start + nargs])
    taken = []
    for word in words[start:]:
        if word.startswith("-") and not _NUMBER.fullmatch(word) and word != "-":
            break
        taken.append(word)
        if nargs in (None, "?"):
            break
    return tuple(taken)


# ------------------------------------------------------------------------------- value types
def _name(fn: Callable[[str], Any], name: str) -> Callable[[str], Any]:
    fn.__name__ = name  # argparse's fallback message says "invalid <name> value"
    return fn


def _bound_text(value: float) -> str:
    return f"{value:g}"


def real(
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    why: str = "",
) -> Callable[[str], float]:
    """A finite float in [lo, hi] (or (lo, hi] with `lo_open`); `why` explains the upper bound.

    >>> real(0, lo_open=True)("0")
    Traceback (most recent call last):
    argparse.ArgumentTypeError: must be > 0, got 0
    """

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
        if lo is not None and (value <= lo if lo_open else value < lo):
            raise argparse.ArgumentTypeError(
                f"must be {'>' if lo_open else '>='} {_bound_text(lo)}, got {text}"
            )
        if hi is not None and value > hi:
            reason = f" ({why})" if why else ""
            raise argparse.ArgumentTypeError(
                f"must be at most {_bound_text(hi)}{reason}, got {text}"
            )
        return value

    return _name(parse, "number")


def finite(bound: float | None = None, why: str = "") -> Callable[[str], float]:
    """A finite float, within ±`bound` when given."""
    if bound is None:
        return real()

    def parse(text: str) -> float:
        value = real()(text)
        if abs(value) > bound:
            reason = f" ({why})" if why else ""
            raise argparse.ArgumentTypeError(
                f"must be between -{_bound_text(bound)} and {_bound_text(bound)}{reason}, "
                f"got {text}"
            )
        return value

    return _name(parse, "number")


def positive(hi: float | None = None, why: str = "") -> Callable[[str], float]:
    """A finite float > 0 (and <= `hi`)."""
    return real(0.0, hi, lo_open=True, why=why)


def non_negative(hi: float | None = None, why: str = "") -> Callable[[str], float]:
    """A finite float >= 0 (and <= `hi`)."""
    return real(0.0, hi, why=why)


def probability() -> Callable[[str], float]:
    """A probability in [0, 1]."""
    return real(0.0, 1.0, why="a probability")


def whole(
    lo: int | None = None, hi: int | None = None, *, why: str = "", also: Iterable[int] = ()
) -> Callable[[str], int]:
    """A whole number in [lo, hi]; the values in `also` are accepted too (``0`` for "off")."""
    extra = tuple(also)

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
        if value in extra:
            return value
        alt = "".join(f" or {v}" for v in extra)
        if lo is not None and value < lo:
            raise argparse.ArgumentTypeError(f"must be >= {lo}{alt}, got {text}")
        if hi is not None and value > hi:
            reason = f" ({why})" if why else ""
            raise argparse.ArgumentTypeError(f"must be at most {hi}{reason}, got {text}")
        return value

    return _name(parse, "whole number")


def seed() -> Callable[[str], int]:
    """A random seed: a whole number in [0, 2^63) (numpy refuses negative seeds)."""
    return whole(0, 2**63 - 1)


def one_of(values: Iterable[int], what: str) -> Callable[[str], int]:
    """A whole number among `values`; the message lists them (``MRCLAM datasets``: 1, ..., 9)."""
    allowed = tuple(values)

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value not in allowed:
            listed = ", ".join(map(str, allowed))
            raise argparse.ArgumentTypeError(f"{what} are {listed}; got {text!r}")
        return value

    return _name(parse, "whole number")


def regex(text: str) -> str:
    """A regular expression that compiles."""
    try:
        re.compile(text)
    except re.error as exc:
        message = f"not a valid regular expression ({exc}): {text!r}"
        raise argparse.ArgumentTypeError(message) from None
    return text


def non_empty(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError("must not be empty")
    return text


# ------------------------------------------------------------------------------ output paths
def check_output_path(path: Path | str, *, folder: bool = False) -> str | None:
    """Why `path` cannot be written (as a file, or as a folder to fill), or None if it can: the
    probe of `ekfslam.files.output_problem`, its message starting with the path the user gave."""
    problem = output_problem(path, folder=folder)
    if problem is None:
        return None
    text = str(path) or repr(str(path))
    shown = text if len(text) <= 160 else f"{text[:80]}...{text[-60:]}"  # a 300-byte name, clipped
    return f"{shown}: {problem}"


def output_file(suffixes: Iterable[str] | None = None) -> Callable[[str], Path]:
    """A file to write; with `suffixes`, its name must end in one of them (no suffix is refused).

    A name without a suffix is refused rather than given one, so the path the command reports
    is the path the user typed.
    """
    allowed = tuple(suffixes) if suffixes is not None else None

    def parse(text: str) -> Path:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"an empty path {text!r}; name a file")
        path = user_path(text)
        if allowed is not None and path.suffix.lower() not in allowed:
            listed = ", ".join(allowed)
            got = f"{path.suffix!r} in {text!r}" if path.suffix else f"no extension in {text!r}"
            raise argparse.ArgumentTypeError(f"the file must end in {listed}; got {got}")
        problem = check_output_path(path)
        if problem is not None:
            raise argparse.ArgumentTypeError(problem)
        return path

    return _name(parse, "path")


def output_folder(text: str) -> Path:
    """A folder to write into (created if missing)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"an empty path {text!r}; name a folder")
    path = user_path(text)
    problem = check_output_path(path, folder=True)
    if problem is not None:
        raise argparse.ArgumentTypeError(problem)
    return path


def given_path(text: str) -> Path:
    """A path to read, as typed (its existence is the reader's to judge); not empty: ``''``
    would mean the current folder."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"an empty path {text!r}; name a file or folder")
    return user_path(text)


def input_path(text: str) -> Path:
    """An existing file or folder to read."""
    path = user_path(text)
    if not path.exists():
        raise argparse.ArgumentTypeError(f"{text} does not exist")
    if not path.is_dir() and not_a_file(path) is not None:  # a FIFO would block the reader
        raise argparse.ArgumentTypeError(f"{text} {not_a_file(path)}")
    return path


def new_run_folder(option: str = "--out") -> Check:
    """A check: the run folder `option` may be written (empty, missing, or ``--overwrite``)."""
    dest = option.lstrip("-").replace("-", "_")

    def check(args: argparse.Namespace) -> str | None:
        path = getattr(args, dest, None)
        if path is None or getattr(args, "overwrite", False):
            return None
        if path.is_dir() and any(path.iterdir()):
            return f"argument {option}: {path} is not empty; pass --overwrite to replace its run"
        return None

    return check


# ---------------------------------------------------------------- options several commands share
def add_json_argument(p: argparse.ArgumentParser, what: str = "print one JSON object") -> None:
    """``--json``: the result as one JSON object on stdout instead of the text table."""
    p.add_argument("--json", action="store_true", help=what)


def mrclam_dataset(text: str) -> Path | int:
    """A MRCLAM dataset, named one way by every command: its folder, or its number 1-9.

    A number is returned as an int, found later by `ekfslam.logs.mrclam.load.find_dataset`
    (the shared data, then the download cache), so parsing stays free of numpy.
    """
    path = user_path(text)
    if path.is_dir():
        return path
    if text.strip().isdigit():
        n = int(text)
        if n in MRCLAM_DATASETS:
            return n
        raise argparse.ArgumentTypeError(f"the MRCLAM datasets are 1 to 9; got {text!r}")
    problem = "is not a folder" if path.exists() else "does not exist"
    raise argparse.ArgumentTypeError(f"{text} {problem}; give a MRCLAM dataset folder or 1-9")


def add_robot_argument(p: argparse.ArgumentParser) -> None:
    """``--robot N`` for commands that read MRCLAM datasets (their robots are 1-5)."""
    p.add_argument(
        "--robot", type=one_of(ROBOTS, "MRCLAM robots"), help="MRCLAM only: which robot (1-5)"
    )


def add_replay_start_arguments(p: Parser) -> None:
    """``--start X Y THETA`` and ``--max-range M``, for the commands that load and replay a run.

    One rule for both formats: the filter starts at ``--start`` when given, else at the run's
    nominal start (run.json's; a MRCLAM robot's Vicon pose, or the origin without its
    RobotN_Groundtruth.dat). ``--max-range``: MRCLAM only, drop sightings beyond M metres
    (`ekfslam.logs.mrclam.checks`; default no cut), counted in the load report.
    """
    p.add_argument(
        "--start",
        nargs=3,
        type=finite(),
        metavar=("X", "Y", "THETA"),
        help="the filter's start pose, m, m, rad (default: the run's nominal start; "
        "the origin for a robot without ground truth)",
    )
    p.add_check(triple_check("--start", (1000.0, 1000.0, math.pi), ("X", "Y", "THETA")))
    add_max_range_argument(p)


def add_max_range_argument(p: argparse.ArgumentParser) -> None:
    """``--max-range M``: the MRCLAM loader drops sightings beyond M m (`mrclam.checks`)."""
    p.add_argument(
        "--max-range",
        type=positive(1000.0, why="m"),
        metavar="M",
        help="MRCLAM only: drop sightings beyond M m, counted (default: keep all; "
        "the dataset's users cut at 6)",
    )


def add_plot_argument(p: argparse.ArgumentParser, what: str) -> None:
    """``--plot FILE``: checked before the work; the suffix names the format and is required."""
    p.add_argument(
        "--plot",
        type=output_file(PLOT_FORMATS),
        metavar="FILE",
        help=f"{what}; FILE must end in {', '.join(PLOT_FORMATS)} (no extension is added); "
        "missing folders are created",
    )


def add_run_folder_arguments(p: Parser, required: bool = True) -> None:
    """``--out DIR --overwrite`` for commands that write a run folder, checked before the work."""
    p.add_argument(
        "--out",
        type=output_folder,
        required=required,
        metavar="DIR",
        help="the run folder to write (created if missing)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace an existing run folder")
    p.add_check(new_run_folder("--out"))


def add_noise_arguments(p: argparse.ArgumentParser) -> None:
    """R (eq. 9), Q (eq. 11) and the filter's choices, for the commands that replay a run."""
    g = p.add_argument_group("noise (R, eq. 9, and Q, eq. 11) and filter options")
    motion = non_negative(MAX_MOTION_SIGMA, why="larger noise swamps every pose")
    g.add_argument("--sigma-x", type=motion, help="motion noise along the body x axis, m/√s")
    g.add_argument("--sigma-y", type=motion, help="motion noise along the body y axis, m/√s")
    g.add_argument("--sigma-theta", type=motion, help="heading noise, rad/√s")
    g.add_argument(
        "--sigma-range", type=positive(MAX_RANGE_SIGMA, why="m"), help="range noise σ_r, m"
    )
    g.add_argument(
        "--sigma-bearing", type=positive(math.pi, why="π rad"), help="bearing noise σ_φ, rad"
    )
    g.add_argument(
        "--init",
        choices=["inverse", "seed"],
        default="inverse",
        help="landmark initialisation: inverse observation (default) or the seed's eq. (3)",
    )
    g.add_argument(
        "--linearization",
        choices=LINEARIZATIONS,
        default="standard",
        help="standard EKF (default), first-estimates Jacobian (fej), or the right-invariant "
        "EKF (invariant; its covariance is reported Cartesian)",
    )
    g.add_argument(
        "--gate",
        type=non_negative(1e6),
        default=CHI2_2DOF_99,
        help="NIS gate (chi-square, 2 dof); 0 turns gating off (default: %(default).2f)",
    )
    g.add_argument(
        "--reinit-after",
        type=whole(2, 10**6, also=(0,)),
        help="re-initialise a landmark after this many agreeing rejected sightings; 0: never "
        "(default: 3, but never for MRCLAM)",
    )


def triple_check(option: str, bounds: tuple[float, float, float], names: tuple[str, ...]) -> Check:
    """A parser check: each of the 3 values of `option` lies within ±its bound."""
    dest = option.lstrip("-").replace("-", "_")

    def check(args: argparse.Namespace) -> str | None:
        values = getattr(args, dest, None)
        if values is None:
            return None
        for name, value, bound in zip(names, values, bounds, strict=True):
            if abs(value) > bound:
                return f"argument {option}: {name} must be within ±{bound:.4g}, got {value:g}"
        return None

    return check
