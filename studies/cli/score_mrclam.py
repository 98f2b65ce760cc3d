"""``python -m studies score-mrclam [DATASET] [--association nn jcbb mht] [--json]``: MRCLAM.

Without ``--association``: the README's MRCLAM table. With it: each robot with the barcodes hidden
from the filter, by the methods named, against the same robot with them known
(`studies.association_mrclam`); ``--linearization L`` runs those replays with filter L;
``--map-noise none`` scores the deciding filter's own map instead of the mapping filter's;
``--time-error independent`` gives each sighting its own time-stamp error instead of one per
image; ``--new-rule density|threshold`` founds landmarks by the likelihood ratio or the NIS
threshold (the default: jcbb the first, mht the second).
``--passes N`` decides each robot's run up to N times, each pass from the last one's map.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math

from ekfslam.analysis.mrclam_tuning import score_robots, scores_table
from ekfslam.cli import args as ca
from ekfslam.cli.common import (
    add_founding_arguments,
    add_hypotheses_argument,
    add_passes_argument,
    mrclam_folder,
    time_shared_of,
)
from ekfslam.core.filter.config import LINEARIZATIONS
from studies.association_mrclam import association_robots, association_table


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``score-mrclam`` (`help` is the one line of `studies.__main__.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help)
    p.add_argument(
        "dataset",
        type=ca.mrclam_dataset,
        nargs="?",
        default=7,
        metavar="DATASET",
        help="a MRCLAM dataset: its folder or its number 1-9 (default: 7)",
    )
    p.add_argument(
        "--association",
        nargs="+",
        choices=("nn", "jcbb", "mht"),
        metavar="METHOD",
        help="hide the barcodes and associate by METHOD (nn, jcbb, mht; one or "
        "more): each robot's map error against known's, and the decisions",
    )
    add_hypotheses_argument(p)
    p.add_argument(
        "--linearization",
        choices=LINEARIZATIONS,
        default=None,
        help="with --association: the filter of the replays that associate (and of "
        "'known, same noise'); known's column stays the shipped standard EKF "
        "(default: standard)",
    )
    p.add_argument(
        "--map-noise",
        choices=("mrclam", "none"),
        default=None,
        help="with --association: the noise of a second filter that maps with the "
        "decisions (mrclam: the consistency noise with sigma_x = sigma_y = 0.005, "
        "the default; none: the deciding filter's own map)",
    )
    add_founding_arguments(p)
    add_passes_argument(p)
    ca.add_json_argument(p, "print one JSON object: {robots: [{robot, landmarks, ...}, ...]}")

    def check(args: argparse.Namespace) -> str | None:
        if args.linearization is not None and not args.association:
            return "argument --linearization: only with --association"
        if args.map_noise is not None and not args.association:
            return "argument --map-noise: only with --association"
        if args.time_error is not None and not args.association:
            return "argument --time-error: only with --association"
        if args.new_rule is not None and not {"jcbb", "mht"} & set(args.association or ()):
            return "argument --new-rule: only with --association jcbb or mht"
        if args.passes != 1 and not args.association:
            return "argument --passes: only with --association"
        if args.passes != 1 and args.linearization == "invariant":
            return "argument --passes: needs the standard or fej filter, not invariant"
        if args.hypotheses is not None and "mht" not in (args.association or ()):
            return "argument --hypotheses: only with --association mht"
        return None

    p.add_check(check)
    p.set_defaults(func=cmd_score_mrclam)


def cmd_score_mrclam(args: argparse.Namespace) -> int:
    # not found: one line saying how to fetch it (an InputError), not a traceback
    folder = mrclam_folder(args.dataset)
    if args.association:
        methods = tuple(dict.fromkeys(args.association))
        rows = association_robots(
            folder,
            methods,
            linearization=args.linearization or "standard",
            hypotheses=args.hypotheses,
            mapped=args.map_noise != "none",
            time_shared=time_shared_of(args),
            new_rule=args.new_rule,
            passes=args.passes,
        )
        if args.json:
            print(
                json.dumps(
                    {"dataset": str(folder), "rows": [_finite(r) for r in rows]},
                    indent=2,
                    allow_nan=False,
                )
            )
        else:
            print(association_table(rows))
        return 0
    scores = score_robots(folder)
    if args.json:
        # JSON has no NaN: a robot without Vicon has no unaligned error or ATE
        robots = [_finite(s) for s in scores]
        print(json.dumps({"dataset": str(folder), "robots": robots}, indent=2, allow_nan=False))
    else:
        print(scores_table(scores))
    return 0


def _finite(row) -> dict:
    """A result row as a dict for JSON, which has no NaN: a missing figure is null."""
    return {
        k: None if isinstance(v, float) and not math.isfinite(v) else v
        for k, v in dataclasses.asdict(row).items()
    }
