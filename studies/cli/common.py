"""What the studies' commands share: where their runs go (``--jobs``, ``--dask``)."""

from __future__ import annotations

import argparse

from ekfslam.cli import args as ca


def _dask_address(text: str) -> str:
    scheme, sep, rest = text.partition("://")
    if not sep or not rest or scheme not in DASK_SCHEMES:
        raise argparse.ArgumentTypeError(
            f"a Dask scheduler address is {'|'.join(DASK_SCHEMES)}://HOST:PORT, got {text!r}"
        )
    return text


DASK_SCHEMES = ("tcp", "tls", "ws", "wss", "inproc")


def add_parallel_arguments(p: argparse.ArgumentParser) -> None:
    """``--jobs N`` and ``--dask ADDRESS``: where the runs go (`ekfslam.analysis.parallel`).

    Every study command that runs in parallel (``consistency``, ``tune-mrclam``) takes them
    from here.
    """
    p.add_argument(
        "--jobs",
        type=ca.whole(1, 4096),
        default=None,
        metavar="N",
        help="local processes for the runs; 1 runs in this process (default: every core)",
    )
    p.add_argument(
        "--dask",
        type=ca._name(_dask_address, "address"),
        metavar="ADDRESS",
        help="run on the Dask cluster at ADDRESS (tcp://host:8786; needs "
        "pip install 'ekfslam[dask]'); --jobs is then ignored",
    )
