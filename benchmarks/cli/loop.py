"""``python -m benchmarks loop [--runs N] [--steps N] [--json]``: see `benchmarks.loop`."""

from __future__ import annotations

import argparse
import json

from benchmarks.loop import RUNS, bench_loop, loop_table
from benchmarks.ukfm_slam2d import STEPS
from ekfslam.cli import args as ca


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``loop`` (`help` is the one line of `benchmarks.__main__.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help)
    p.add_argument(
        "--runs", type=ca.whole(1, 1000), default=RUNS, help="runs (default: %(default)s)"
    )
    p.add_argument(
        "--steps",
        type=ca.whole(10, 100_000),
        default=STEPS,
        help="steps a run, >= 10 (default: ukfm's %(default)s)",
    )
    ca.add_json_argument(p, "print the results as JSON")
    p.set_defaults(func=cmd_loop)


def cmd_loop(args: argparse.Namespace) -> int:
    r = bench_loop(args.runs, args.steps)
    print(json.dumps(r, indent=2, allow_nan=False) if args.json else loop_table(r))
    return 0
