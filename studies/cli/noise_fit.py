"""``python -m studies noise-fit [--datasets D ...] [--jobs N] [--json]``: issue 39,
``--noise fit`` never worse than the default it starts from.

Every robot of MRCLAM Datasets 1, 2, 4 and 7 by ``run --noise fit``
(`ekfslam.analysis.noise_fit.fit_from_default`): the default's map, the fit's, which was kept
and the kept map against the default's (`studies.noise_fit`).
"""

from __future__ import annotations

import argparse
import json

from ekfslam.cli import args as ca
from studies.noise_fit import DATASETS, measure, summary, table


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``noise-fit`` (`help` is the one line of `studies.__main__.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--jobs",
        type=ca.whole(1, 4096),
        default=1,
        metavar="N",
        help="local processes for the robots (default 1)",
    )
    p.add_argument(
        "--datasets",
        nargs="+",
        type=int,
        choices=DATASETS,
        default=DATASETS,
        metavar="D",
        help="the MRCLAM datasets (default: 1 2 4 7)",
    )
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    p.set_defaults(func=cmd_noise_fit)


def cmd_noise_fit(args: argparse.Namespace) -> int:
    rows = measure(args.jobs, args.datasets)
    if args.json:
        print(json.dumps(rows, indent=1))
    else:
        print(table(rows))
        print(summary(rows))
    return 0
