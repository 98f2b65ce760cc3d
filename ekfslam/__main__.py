"""``python -m ekfslam``: see `ekfslam.cli.main`."""

import signal
import sys


def _ended(signum: int, frame: object) -> None:
    """A signal while Python still imports the command line: nothing is written yet, so end at
    once, with the one line and the status the command line gives (`ekfslam.files`' handlers
    take over when the command starts)."""
    name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
    print(f"interrupted ({name}): stopped; no file was left half-written", file=sys.stderr)
    sys.exit(128 + signum)


signal.signal(signal.SIGTERM, _ended)
signal.signal(signal.SIGINT, _ended)

from ekfslam.cli.main import exit_with, main  # noqa: E402  (after the handlers: importing takes a while)

exit_with(main())
