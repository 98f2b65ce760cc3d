"""`python -m ekfslam ...` as a user runs it: a fresh interpreter, captured output, no window.

One helper for the test files that drive the command line (pytest puts ``tests/`` on the path).
"""

from __future__ import annotations

import functools
import importlib
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from ekfslam.cli.main import main

REPO = Path(__file__).resolve().parents[1]


def run_ekfslam(
    *args: str, cwd: Path = REPO, env: dict | None = None
) -> subprocess.CompletedProcess:
    """Run ``python -m ekfslam ARGS`` with matplotlib's Agg backend; at most 300 s."""
    return run_module("ekfslam", *args, cwd=cwd, env=env)


def run_module(
    module: str, *args: str, cwd: Path = REPO, env: dict | None = None
) -> subprocess.CompletedProcess:
    """Run ``python -m MODULE ARGS`` (ekfslam, or the checkout's studies and benchmarks, which
    run from its root) with matplotlib's Agg backend; at most 300 s."""
    return subprocess.run(
        [sys.executable, "-m", module, *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "MPLBACKEND": "Agg", **(env or {})},
    )


def main_of(module: str) -> Callable[[list[str]], int]:
    """``python -m MODULE ARGV`` in this process, for studies and benchmarks: the shared command
    line (`ekfslam.cli.main.main`) with that folder's table of commands; returns the status."""
    table = importlib.import_module(f"{module}.__main__")
    return functools.partial(
        main, commands=table.COMMANDS, prog=f"python -m {module}", description=table.DESCRIPTION
    )
