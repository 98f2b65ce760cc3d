"""``python -m benchmarks COMMAND ...`` from a checkout's root: the project's benchmarks.

The same lazy table of commands as ``python -m ekfslam`` (`ekfslam.cli.main`), with the same
one-line refusals of bad input; only the chosen command's module is imported.
"""

from __future__ import annotations

from ekfslam.cli.main import exit_with, main

#: command -> (its module, its one line in ``--help``), in the order ``--help`` lists them.
COMMANDS: dict[str, tuple[str, str]] = {
    "bench": ("benchmarks.cli.bench", "time replays and per-step costs against map size"),
    "loop": (
        "benchmarks.cli.loop",
        "time a user's own loop of the step API against ukfm's EKF on ukfm's 2D SLAM world",
    ),
    "tune": ("benchmarks.cli.tune", "time the live tuning panel's change-to-figure latency"),
    "grading": ("benchmarks.cli.grading", "time lab grade on a class of sandboxed submissions"),
}
DESCRIPTION = "The ekfslam project's benchmarks: the filter, the commands, the live panel."

if __name__ == "__main__":
    exit_with(main(commands=COMMANDS, prog="python -m benchmarks", description=DESCRIPTION))
