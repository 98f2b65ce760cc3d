"""``python -m ekfslam fetch mrclam N [--cache DIR] [--url URL]``: prints the dataset's path."""

from __future__ import annotations

import argparse

from ekfslam.cli import args as ca
from ekfslam.logs.mrclam.cache import CACHE_DEFAULT_HELP, DATASETS
from ekfslam.logs.mrclam.fetch import fetch_mrclam


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``fetch`` (`help` is the one line of `ekfslam.cli.main.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help)
    p.add_argument("dataset", choices=["mrclam"], help="which dataset family")
    p.add_argument(
        "number", type=ca.one_of(DATASETS, "the MRCLAM datasets"), help="MRCLAM dataset number, 1-9"
    )
    p.add_argument(
        "--cache", type=ca.output_folder, help=f"cache folder (default: {CACHE_DEFAULT_HELP})"
    )
    p.add_argument(
        "--url",
        type=_base_url,
        help="base URL holding MRCLAM<N>.zip (default: $EKFSLAM_MRCLAM_URL)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_fetch)


def _base_url(text: str) -> str:
    if not text.startswith(("http://", "https://", "file://")):
        raise argparse.ArgumentTypeError(
            f"must start with http://, https:// or file://, got {text!r}"
        )
    return text


def cmd_fetch(args: argparse.Namespace) -> int:
    path = fetch_mrclam(
        args.number, cache_dir=args.cache, base_url=args.url, progress=not args.quiet
    )
    print(path)
    return 0
