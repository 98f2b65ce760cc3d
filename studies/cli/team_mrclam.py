"""``python -m studies team-mrclam [DATASET ...] [--json]``: MRCLAM's robots alone and in one map
(`studies.team_mrclam`); by default every dataset found (1, 2, 4, 7 in the shared data)."""

from __future__ import annotations

import argparse
import dataclasses
import json

from ekfslam.cli import args as ca
from ekfslam.cli.common import mrclam_folder
from ekfslam.errors import InputError
from ekfslam.logs.mrclam.load import find_dataset
from studies.team_mrclam import markdown, study_dataset


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``team-mrclam``."""
    p = subparsers.add_parser(name, help=help)
    p.add_argument(
        "datasets",
        type=ca.mrclam_dataset,
        nargs="*",
        metavar="DATASET",
        help="MRCLAM datasets, folders or numbers 1-9 (default: every one that is found)",
    )
    ca.add_json_argument(p)
    p.set_defaults(func=cmd_team_mrclam)


def cmd_team_mrclam(args: argparse.Namespace) -> int:
    chosen = list(args.datasets)
    if not chosen:
        for n in range(1, 10):
            try:
                find_dataset(n)
            except InputError:
                continue
            chosen.append(n)
        if not chosen:
            find_dataset(7)  # raises: where it looked, and how to fetch it
    rows = [study_dataset(mrclam_folder(dataset)) for dataset in chosen]
    if args.json:
        out = [
            dataclasses.asdict(row) | {"alone_mean": row.alone_mean, "alone_best": row.alone_best}
            for row in rows
        ]
        print(json.dumps(out, indent=2))
    else:
        print(markdown(rows))
    return 0
