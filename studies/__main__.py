"""``python -m studies COMMAND ...`` from a checkout's root: the project's studies.

The same lazy table of commands as ``python -m ekfslam`` (`ekfslam.cli.main`), with the same
one-line refusals of bad input; only the chosen command's module is imported.
"""

from __future__ import annotations

from ekfslam.cli.main import exit_with, main

#: command -> (its module, its one line in ``--help``), in the order ``--help`` lists them.
COMMANDS: dict[str, tuple[str, str]] = {
    "score-mrclam": (
        "studies.cli.score_mrclam",
        "replay every robot of a MRCLAM dataset with one noise setting; print the scores",
    ),
    "tune-mrclam": (
        "studies.cli.tune_mrclam",
        "tune the MRCLAM noise over datasets; --cross-validate: leave one dataset out",
    ),
    "consistency": (
        "studies.cli.consistency",
        "NEES/NIS over Monte Carlo runs; outlier gating; a long Σ run; MRCLAM against Vicon",
    ),
    "budget": (
        "studies.cli.budget",
        "the realistic robot's error budget: each error source alone and all but it",
    ),
    "team-mrclam": (
        "studies.cli.team_mrclam",
        "each MRCLAM dataset's robots alone and in one joint map: map and trajectory errors",
    ),
    "association-auto": (
        "studies.cli.association_auto",
        "with hidden ids: every MRCLAM robot by nn, jcbb, mht, two passes and auto; thresholds",
    ),
    "noise-fit": (
        "studies.cli.noise_fit",
        "--noise fit on every MRCLAM robot: the default's map, the fit's, the one kept",
    ),
    "vision-eval": (
        "studies.cli.vision_eval",
        "score range and bearing from rendered frames against the truth",
    ),
}
DESCRIPTION = "The ekfslam project's studies: what chose the defaults, what the README reports."

if __name__ == "__main__":
    exit_with(main(commands=COMMANDS, prog="python -m studies", description=DESCRIPTION))
