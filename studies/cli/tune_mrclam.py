"""``python -m studies tune-mrclam [DATASET ...] [--cross-validate] [--table FILE | --out FILE]``.

Replays every robot of the datasets (default 7, 1 and 4) at every point of the noise grid
(`studies.mrclam_tuning.TUNING_GRID`, 81 points: 1,215 replays, a minute or two on two
cores) and prints the best settings over all of them; ``--cross-validate`` prints the
leave-one-dataset-out folds instead (tune on all datasets but one, score the one left out) and
the default they choose (`studies.mrclam_crossval`). ``--out FILE.json`` keeps the
grid's table; ``--table FILE.json`` reads one back instead of replaying (the recorded table is
``ekfslam/logs/mrclam/crossval.json``).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from ekfslam.cli import args as ca
from ekfslam.cli.common import mrclam_folder
from ekfslam.errors import ConfigError
from ekfslam.files import atomic_write_text
from studies.cli.common import add_parallel_arguments
from studies.mrclam_crossval import (
    DATASETS,
    measure_grid,
    read_table,
    report,
    report_text,
)

#: rows the in-sample ranking prints
TOP = 5


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``tune-mrclam`` (`help` is the one line of `studies.__main__.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[1])
    p.add_argument(
        "datasets",
        type=ca.mrclam_dataset,
        nargs="*",
        metavar="DATASET",
        help="MRCLAM datasets: folders or numbers 1-9 (default: 7 1 4)",
    )
    p.add_argument(
        "--cross-validate",
        action="store_true",
        help="leave one dataset out: tune on the others, score it",
    )
    source = p.add_mutually_exclusive_group()
    source.add_argument(
        "--table",
        type=ca.input_path,
        metavar="FILE.json",
        help="read the grid's table (from --out) instead of replaying",
    )
    source.add_argument(
        "--out",
        type=ca.output_file([".json"]),
        metavar="FILE.json",
        help="write the table (each robot at each point) to FILE.json",
    )
    add_parallel_arguments(p)
    ca.add_json_argument(p, "print one JSON object (the folds, or the ranking)")
    p.set_defaults(func=cmd_tune_mrclam)


def cmd_tune_mrclam(args: argparse.Namespace) -> int:
    if args.table is not None:
        if args.datasets:
            raise ConfigError("tune-mrclam: give DATASETs or --table, not both")
        table = read_table(args.table)
    else:
        named = args.datasets or list(DATASETS)
        if args.cross_validate and len(named) < 2:  # before minutes of replays, not after
            raise ConfigError("tune-mrclam --cross-validate needs at least two datasets")
        folders = {_label(d): mrclam_folder(d) for d in named}
        if len(folders) < len(named):
            raise ConfigError("tune-mrclam: a dataset is named twice")
        table = measure_grid(folders, jobs=args.jobs, dask=args.dask)
        if args.out is not None:
            atomic_write_text(args.out, json.dumps(table.as_dict(), allow_nan=False) + "\n")
    if args.cross_validate:
        if len(table.datasets) < 2:
            raise ConfigError(
                f"{args.table}: a table of {len(table.datasets)} dataset; --cross-validate needs "
                "at least two datasets"
            )
        if args.json:
            print(json.dumps(report(table), indent=2, allow_nan=False))
        else:
            print(report_text(table))
    else:
        _ranking(table, args.json)
    if args.out is not None:
        print(f"table written to {args.out}")
    return 0


def _label(dataset) -> str:
    return str(dataset) if isinstance(dataset, int) else dataset.name


def _ranking(table, as_json: bool) -> None:
    """In-sample: the grid ranked by the mean over every robot of every dataset."""
    errors = np.asarray(table.errors)
    order = np.argsort(errors.mean(axis=(1, 2)), kind="stable")[:TOP]
    rows = [
        {"noise": table.points[i], "mean": float(errors[i].mean()), "max": float(errors[i].max())}
        for i in order
    ]
    if as_json:
        print(json.dumps({"datasets": list(table.datasets), "best": rows}, indent=2))
        return
    print(f"in-sample over {' + '.join(table.datasets)}: mean and worst robot (m), best first")
    for r in rows:
        noise = ", ".join(f"{k} {v:g}" for k, v in r["noise"].items())
        print(f"{r['mean']:.4f}  {r['max']:.3f}  {noise}")
