"""``python -m studies association-auto [--refresh STRATEGY ...] [--jobs N] [--json]``: issue 39.

Every robot of MRCLAM Datasets 1, 2, 4 and 7 with the ids hidden, by each strategy of
`studies.association_auto.STRATEGIES` (``known``, ``nn``, ``jcbb``, ``jcbb x2``, ``mht``,
``mht h3``, ``auto``): the map against known's, the diagnosis and the filter's seconds; then the
association thresholds and the escalation chosen leaving one dataset out. The replays are
stored in ``studies/results/association_auto.json``; the table is printed from it, and
``--refresh`` measures the strategies named again (``all``: every one).
"""

from __future__ import annotations

import argparse
import json

from studies.association_auto import STRATEGIES, cached, leave_one_dataset_out, report


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``association-auto`` (`help` is the one line of `studies.__main__.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--refresh",
        nargs="+",
        choices=(*STRATEGIES, "all"),
        default=(),
        metavar="STRATEGY",
        help="measure these strategies again (all: every one) instead of reading them",
    )
    p.add_argument(
        "--jobs",
        type=int,
        default=1,
        metavar="N",
        help="local processes for the replays (default 1: the filter seconds are one core's)",
    )
    p.add_argument("--json", action="store_true", help="print the rows and folds as JSON")
    p.set_defaults(func=cmd_association_auto)


def cmd_association_auto(args: argparse.Namespace) -> int:
    refresh = STRATEGIES if "all" in args.refresh else args.refresh
    rows = cached(refresh, args.jobs)
    if args.json:
        print(json.dumps({"rows": rows, "folds": leave_one_dataset_out(rows)}, indent=1))
    else:
        print(report(rows))
    return 0
