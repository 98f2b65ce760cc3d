"""``python -m benchmarks bench [--quick] [--json] [--out DIR]``: see `benchmarks.bench`."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from benchmarks.bench import (
    MAX_SIZE,
    MRCLAM_SKIPPED,
    REPEATS,
    SIZES,
    BenchConfig,
    default_mrclam_dir,
    run_benchmarks,
)
from benchmarks.figure import plot_costs
from benchmarks.report import markdown_table, write_outputs
from ekfslam.cli import args as ca
from ekfslam.cli.common import mrclam_folder

DEFAULT_OUT = Path("out/bench")


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``bench`` (`help` is the one line of `benchmarks.__main__.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help)
    p.add_argument("--quick", action="store_true", help="fewer repeats (about a minute)")
    ca.add_json_argument(p, "print the results as JSON")
    p.add_argument(
        "--out",
        type=ca.output_folder,
        default=DEFAULT_OUT,
        help="where to write the table, the JSON and the plot (default: %(default)s; "
        "created if missing)",
    )
    p.add_argument(
        "--sizes",
        type=ca.whole(1, MAX_SIZE, why="Σ would not fit in memory"),
        nargs="+",
        help=f"map sizes n, 1 to {MAX_SIZE} (default: {SIZES})",
    )
    p.add_argument(
        "--repeats",
        type=ca.whole(1, 1000),
        help="repeats of every measurement, >= 1 (a smoke run: 1; default: the "
        "config's, fewer with --quick)",
    )
    p.add_argument(
        "--mrclam",
        type=ca.mrclam_dataset,
        metavar="DATASET",
        help="the MRCLAM dataset to replay robot 1 of: its folder or its number "
        "1-9 (default: 7, from the shared data or the download cache)",
    )
    p.add_argument("--no-mrclam", action="store_true", help="skip the MRCLAM replay")
    p.set_defaults(func=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> int:
    kwargs: dict = {
        "mrclam_dir": None
        if args.no_mrclam
        else (mrclam_folder(args.mrclam) if args.mrclam else default_mrclam_dir())
    }
    if args.no_mrclam:
        kwargs["mrclam_note"] = MRCLAM_SKIPPED
    if args.sizes:
        kwargs["sizes"] = tuple(sorted(set(args.sizes)))
    if args.repeats is not None:
        kwargs.update(dict.fromkeys(REPEATS, args.repeats))
    config = BenchConfig.quick(**kwargs) if args.quick else BenchConfig(**kwargs)
    r = run_benchmarks(config, command=_command(args))
    write_outputs(r, args.out)
    plot_costs(r, args.out / "cost_vs_n.png")
    if args.json:
        print(json.dumps(r, indent=2, allow_nan=False))
    else:
        print(markdown_table(r))
        print(f"\nwritten: {args.out / 'bench.md'}, bench.json, cost_vs_n.png")
    return 0


def _command(args: argparse.Namespace) -> str:
    """The command line that reproduces this run."""
    flags = [("--quick", args.quick), ("--json", args.json), ("--no-mrclam", args.no_mrclam)]
    options = [
        ("--out", None if args.out == DEFAULT_OUT else args.out),
        ("--sizes", " ".join(map(str, args.sizes)) if args.sizes else None),
        ("--repeats", args.repeats),
        ("--mrclam", None if args.no_mrclam else args.mrclam),
    ]
    parts = [flag for flag, on in flags if on] + [f"{o} {v}" for o, v in options if v is not None]
    return " ".join(["python -m benchmarks bench", *parts])
