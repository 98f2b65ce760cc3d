"""The command line: ``python -m ekfslam run|simulate|fetch ...``, a lazy table of commands.

`COMMANDS` names each command's module and its one line of help. The top-level parser lists
every command from that table and imports ONLY the chosen command's module, which adds its own
subparser (``add_command(subparsers, name, help)``): ``python -m ekfslam --help`` loads no command,
no numpy, no numba, no cv2, and ``run`` loads what a replay needs and nothing else.

Bad input ends with one line on stderr that names the file, the line and the problem, and exit
status 2; never a traceback. A bad option value or output path is refused the same way while
the command line is parsed, before any work (the types and checks are in `ekfslam.cli.args`).
Ctrl-C (SIGINT) and SIGTERM end a command with one line and exit status 130 and 143 (128 + the
signal), after every temporary file is removed (`ekfslam.files.interrupts_raise`).
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
import warnings
from typing import NoReturn

from ekfslam.cli import args as ca
from ekfslam.errors import (
    MAX_MESSAGE,
    ConfigError,
    EkfSlamError,
    InputError,
    Interrupted,
    OutputError,
    one_line,
)
from ekfslam.files import interrupts_raise

EXIT_BAD_INPUT = 2

#: command -> (its module, its one line in ``--help``), in the order ``--help`` lists them.
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("ekfslam.cli.run", "replay a run (our run-log folder, or a MRCLAM dataset)"),
    "simulate": ("ekfslam.cli.simulate", "simulate the seed's robot and write a run folder"),
    "fetch": ("ekfslam.cli.fetch", "download a public dataset into the cache"),
    "fit-noise": (
        "ekfslam.cli.fit_noise",
        "fit R and Q to a run's innovations (maximum likelihood, no ground truth)",
    ),
    "convert": (
        "ekfslam.cli.convert",
        "convert a recorded log (MRCLAM, ROS bag) to a run folder",
    ),
    "tum": (
        "ekfslam.cli.tum",
        "replay a run (ours or MRCLAM) and write trajectory and map as TUM files for evo",
    ),
    "render-frames": (
        "ekfslam.cli.frames",
        "render the camera frames of a simulated run (a run of frames, no detections)",
    ),
    "detect": (
        "ekfslam.cli.frames",
        "detect the AprilTags in a run's camera frames -> detections.csv",
    ),
    "warm": (
        "ekfslam.cli.warm",
        "compile the filter's steps into numba's cache once, so that no first use waits",
    ),
    "lab": (
        "ekfslam.cli.lab",
        "the lab for a course: release the students' copy; grade submissions into a CSV",
    ),
}


#: What ``python -m ekfslam --help`` says the commands are for.
DESCRIPTION = "Landmark EKF SLAM after the UCSD CSE276A HW3 report."


def build_parser(
    argv: list[str] | None = None,
    commands: dict[str, tuple[str, str]] = COMMANDS,
    prog: str = "python -m ekfslam",
    description: str = DESCRIPTION,
) -> ca.Parser:
    """The parser, with the full subparser of the command named in `argv` only.

    The other commands are listed with their help but get no options: parsing stops at the
    command's name, so only that command's options (and its module) are ever needed. `commands`
    is a table like `COMMANDS`: the repository's ``python -m studies`` and ``python -m
    benchmarks`` run their own through this same parser.
    """
    parser = ca.Parser(prog=prog, description=description)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=ca.Parser)
    chosen = command_in(sys.argv[1:] if argv is None else argv, commands)
    for name, (module, help_line) in commands.items():
        if name == chosen:
            importlib.import_module(module).add_command(sub, name, help_line)
        else:
            sub.add_parser(name, help=help_line)
    return parser


def command_in(argv: list[str], commands: dict[str, tuple[str, str]] = COMMANDS) -> str | None:
    """The command `argv` names: its first word that is not an option (the top level has no
    option that takes a value), or None."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in commands else None
    return None


def _one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning on the command line is one line that says what happened, not where in our code."""
    print(f"warning: {' '.join(str(message).split())}", file=sys.stderr if file is None else file)


def main(
    argv: list[str] | None = None,
    commands: dict[str, tuple[str, str]] = COMMANDS,
    prog: str = "python -m ekfslam",
    description: str = DESCRIPTION,
) -> int:
    """Run one command of `commands`; returns its exit status (2: a bad option, path or input,
    one line; 130 or 143: ended by Ctrl-C or SIGTERM)."""
    try:
        with interrupts_raise():
            return _run(argv, commands, prog, description)
    except BaseException as exc:
        signum = _signal_in(exc)
        if signum is None:
            raise
        name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        print(f"interrupted ({name}): stopped; no file was left half-written", file=sys.stderr)
        return 128 + signum


def exit_with(code: int) -> NoReturn:
    """End the process with `code`, as ``python -m ekfslam`` (and the repository's studies and
    benchmarks) do after `main`. After a signal every clean-up has already run, and the
    interpreter's teardown is skipped: a native library interrupted mid-call (OpenCV's video
    writer) has been seen to crash there (exit -11 after the one line), which would turn a
    clean 143 into a segfault."""
    if code in (128 + signal.SIGINT, 128 + signal.SIGTERM):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def _signal_in(exc: BaseException | None) -> int | None:
    """The signal that ended the command, if `exc` is an interrupt or was caused by one: an
    interrupt while a C extension initialises reaches us as an ImportError, say."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, Interrupted):
            return exc.signum
        if isinstance(exc, KeyboardInterrupt):  # Ctrl-C before our handlers were set
            return int(signal.SIGINT)
        exc = exc.__cause__ or exc.__context__
    return None


def _run(
    argv: list[str] | None, commands: dict[str, tuple[str, str]], prog: str, description: str
) -> int:
    parser = build_parser(argv, commands, prog, description)
    try:
        args = parser.parse_args(argv)  # a bad option ends here, before any work
    except SystemExit as exc:  # --help (0) or a refused option (2): a status, as for the rest
        return exc.code if isinstance(exc.code, int) else EXIT_BAD_INPUT
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning
            return args.func(args)
    except BrokenPipeError:  # `... | head` closed our stdout: not an error of ours
        # Python would complain again when it flushes stdout at exit
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except (InputError, ConfigError, OutputError) as exc:
        print(f"error: {one_line(str(exc), MAX_MESSAGE)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except EkfSlamError as exc:
        print(f"error: {one_line(str(exc), MAX_MESSAGE)}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
