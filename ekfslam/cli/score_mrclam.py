"""``python -m ekfslam score-mrclam [DATASET] [--json]``: the README's MRCLAM table, measured."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math

from ekfslam.analysis.mrclam_tuning import score_robots, scores_table
from ekfslam.cli import args as ca
from ekfslam.cli.common import mrclam_folder


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``score-mrclam`` (`help` is the one line of `ekfslam.cli.main.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help)
    p.add_argument("dataset", type=ca.mrclam_dataset, nargs="?", default=7, metavar="DATASET",
                   help="a MRCLAM dataset: its folder or its number 1-9 (default: 7)")  # fmt: skip
    ca.add_json_argument(p, "print one JSON object: {robots: [{robot, landmarks, ...}, ...]}")
    p.set_defaults(func=cmd_score_mrclam)


def cmd_score_mrclam(args: argparse.Namespace) -> int:
    # not found: one line saying how to fetch it (an InputError), not a traceback
    folder = mrclam_folder(args.dataset)
    scores = score_robots(folder)
    if args.json:
        # JSON has no NaN: a robot without Vicon has no unaligned error or ATE
        robots = [
            {k: None if isinstance(v, float) and not math.isfinite(v) else v
             for k, v in dataclasses.asdict(s).items()}
            for s in scores
        ]  # fmt: skip
        print(json.dumps({"dataset": str(folder), "robots": robots}, indent=2, allow_nan=False))
    else:
        print(scores_table(scores))
    return 0
