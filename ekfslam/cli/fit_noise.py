"""``python -m ekfslam fit-noise RUN [--robot N] [--json]``: R and Q from the log itself.

Maximum likelihood of the innovations, no ground truth (`ekfslam.analysis.noise_fit`); prints the
fitted σ with their uncertainty and the NIS check of a replay with them, and which noise to
keep: the fit, or the rescued default it started from when the fit replays worse
(`ekfslam.analysis.noise_fit.fit_from_default`). ``run RUN --noise fit``
fits the same way and replays with the result.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ekfslam.analysis.noise_fit import fit_from_default
from ekfslam.cli import args as ca
from ekfslam.cli.common import add_iterations_argument, load_run, noise_from_args
from ekfslam.core.noise import NoiseConfig


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``fit-noise`` (`help` is the one line of `ekfslam.cli.main.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[0])
    p.add_argument("run", type=Path, help="a run folder or a MRCLAM dataset folder")
    ca.add_robot_argument(p)
    ca.add_replay_start_arguments(p)
    ca.add_json_argument(p, "print one JSON object: {noise, white, correlation, ..., nis_check}")
    ca.add_noise_arguments(p)  # where the search starts, and the filter's gate
    add_iterations_argument(p)
    p.set_defaults(func=cmd_fit_noise)


def cmd_fit_noise(args: argparse.Namespace) -> int:
    run, _report = load_run(args)
    start, config = noise_from_args(args, run)
    # the fit starts from the rescued default and is kept only when it replays no worse
    choice = fit_from_default(run, start, config)
    if args.json:
        print(json.dumps({"name": run.meta.name, **choice.as_dict()}, indent=2, allow_nan=False))
    else:
        print(f"noise fitted to {run.meta.name}'s innovations:")
        print("\n".join(choice.fit.lines()))
        print(choice.line())
        print(f"replay with it: {replay_hint(choice.noise)}")
    return 0


def replay_hint(n: NoiseConfig) -> str:
    """The ``run`` options that replay with the kept noise (or ``--noise fit``, which refits)."""
    return (
        f"--sigma-x {n.sigma_x:.4g} --sigma-y {n.sigma_y:.4g} --sigma-theta {n.sigma_theta:.4g} "
        f"--sigma-range {n.sigma_range:.4g} --sigma-bearing {n.sigma_bearing:.4g} "
        "(or run ... --noise fit)"
    )
