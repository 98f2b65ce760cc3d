"""``python -m ekfslam tune --bench [--repeats N] [--json]``: the live panel's latency per run.

The panel itself lives in a notebook (`ekfslam.ui.widgets.tuning_panel`); this command times what
one slider change costs, from the change to the redrawn figure, on each seed run.
"""

from __future__ import annotations

import argparse
import json

from ekfslam.cli import args as ca
from ekfslam.ui.latency import benchmark


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``tune`` (`help` is the one line of `ekfslam.cli.main.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[0])
    p.add_argument("--bench", action="store_true", help="time the panel's update")
    p.add_argument("--repeats", type=ca.whole(1, 1000), default=15,
                   help="samples per run (default: %(default)s)")  # fmt: skip
    ca.add_json_argument(p)
    p.set_defaults(func=cmd_tune, print_help=p.print_help)


def cmd_tune(args: argparse.Namespace) -> int:
    if not args.bench:
        args.print_help()
        return 0
    results = benchmark(repeats=args.repeats)
    if args.json:
        print(json.dumps(results, indent=2, allow_nan=False))
        return 0
    for name, r in results.items():
        print(
            f"{name:<16} median {r['median_ms']:6.1f} ms = replay {r['replay_ms']:.1f} ms "
            f"+ summary and artists {r['update_ms'] - r['replay_ms']:.1f} ms "
            f"+ render to PNG {r['draw_ms']:.1f} ms; CPU time {r['cpu_ms']:.1f} ms "
            f"({r['samples']} samples; target 100 ms)"
        )
    return 0
