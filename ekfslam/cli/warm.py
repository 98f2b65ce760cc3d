"""``python -m ekfslam warm [--quiet]``: compile the filter's steps into numba's cache once, so that
no later use waits for it.

It calls every step a user's loop and a replay call, compiled (`FilterConfig(backend="numba")`),
for each linearisation, with and without a history, then writes the marker
(`ekfslam.core.filter.compile.warm_stamp`) by which a filter on backend "auto" knows that the
compiled steps load in a second. A filter that has run enough events on a cold cache starts this
command in a process of its own and keeps the Python steps until it is done
(`ekfslam.core.filter.backend.auto_steps`). About a minute on a cold cache, a second or two on
a warm one.
"""

from __future__ import annotations

import argparse
import importlib
import time

import numpy as np

from ekfslam.core.filter.backend import COMPILER, ROOTS, models_of
from ekfslam.core.filter.config import LINEARIZATIONS, FilterConfig
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.models import ODOMETRY, RANGE_BEARING


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``warm`` (`help` is the one line of `ekfslam.cli.main.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help)
    p.add_argument("--quiet", action="store_true", help="print nothing")
    p.set_defaults(func=cmd_warm)


def cmd_warm(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    warm()
    if not args.quiet:
        print(f"the filter's compiled steps are in the cache ({time.perf_counter() - t0:.1f} s)")
    return 0


def warm() -> None:
    """Call the seed models' compiled steps as the filter calls them; then mark the cache warm."""
    Q, M = np.diag([0.01, 0.001]), np.diag([1e-3, 1e-4, 1e-4])
    for linearization in LINEARIZATIONS:
        for record in (False, True):
            f = EKFSLAM(
                np.zeros(3),
                config=FilterConfig(linearization=linearization, backend="numba"),
                record=record,
            )
            f.predict(np.array([0.1, 0.0, 0.01]), np.eye(3) * 1e-4, 0.5)
            f.predict_many(np.array([[0.1, 0.0, 0.01]]), np.ones(1), np.ones(1), M=M)
            for t in (1.0, 2.0):
                f.update(1, np.array([2.0, 0.1]), Q, t)
            _ = f.Sigma, f.pose_covariance
    compiler = importlib.import_module(COMPILER)
    compiler.warm_stamp(ROOTS, models_of(ODOMETRY, RANGE_BEARING)).touch()
