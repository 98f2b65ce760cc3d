"""``python -m studies budget square|octagon [--seeds N ...] [--json] [--plot FILE]``: the
realistic robot's error budget (`ekfslam.analysis.error_budget`), one source at a time.

Each error source of `ekfslam.sim.config.REALISTIC` alone on the ideal robot, and every source
but it, averaged over the seeds, all replayed with the realistic robot's noise
(`ekfslam.sim.scenarios.realistic_noise`); the last lines are the ideal and the realistic
robots, and the seed's real robot (Table 1). Notebook 07 shows the same table for seeds 1-4.
"""

from __future__ import annotations

import argparse
import dataclasses
import json

from ekfslam.analysis.error_budget import error_budget
from ekfslam.analysis.evaluation import SEED_TABLE1
from ekfslam.cli import args as ca
from ekfslam.files import save_figure
from ekfslam.sim.config import REALISTIC, TRAJECTORIES
from ekfslam.sim.scenarios import realistic_noise
from ekfslam.viz.budget import budget_figure, budget_text

#: The seeds averaged over by default: one seed's budget moves by a centimetre from seed to seed.
DEFAULT_SEEDS = tuple(range(1, 9))


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``budget`` (`help` is the one line of `studies.__main__.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[1])
    p.add_argument("trajectory", choices=TRAJECTORIES, help="the seed's experiment: two laps")
    p.add_argument(
        "--seeds",
        type=ca.seed(),
        nargs="+",
        default=list(DEFAULT_SEEDS),
        metavar="N",
        help="simulation seeds to average over (default: 1 to 8; each "
        f"costs {2 + 2 * len(REALISTIC)} simulations and replays, about a "
        "second)",
    )
    ca.add_json_argument(p, "print one JSON object: {trajectory, seeds, ideal, realistic, rows}")
    ca.add_plot_argument(p, "draw each source alone and what fixing it saves to FILE")
    p.add_check(_distinct_seeds)
    p.set_defaults(func=cmd_budget)


def _distinct_seeds(args: argparse.Namespace) -> str | None:
    seen: set[int] = set()
    for s in args.seeds:
        if s in seen:
            return f"argument --seeds: seed {s} is given twice (each seed counts once)"
        seen.add(s)
    return None


def cmd_budget(args: argparse.Namespace) -> int:
    budget = error_budget(args.trajectory, seeds=args.seeds)
    seed_error = SEED_TABLE1[args.trajectory][3]  # m: the seed's real robot, Table 1
    if args.plot is not None:
        save_figure(budget_figure([budget], {args.trajectory: seed_error}), args.plot)
    if args.json:
        out = dataclasses.asdict(budget) | {
            "seed_report": seed_error,
            "noise": dataclasses.asdict(realistic_noise()),
            "plot": None if args.plot is None else str(args.plot),
        }
        print(json.dumps(out, indent=2, allow_nan=False))
    else:
        width = max(len(r.source) for r in budget.rows) + 2
        print(budget_text(budget))
        label = "the seed's robot"
        print(f"{label:<{width}}{1000 * seed_error:>8.0f}")
        if args.plot is not None:
            print(f"figure: {args.plot}")
    return 0
