"""`python -m studies ...` as it runs from a checkout: a fresh interpreter, or in this process.

One helper for the test files that drive the studies' command line (pytest puts this folder on
the path).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from ekfslam.cli.main import main
from studies.__main__ import COMMANDS, DESCRIPTION

REPO = Path(__file__).resolve().parents[2]


def run_studies(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """Run ``python -m studies ARGS`` from the checkout's root with matplotlib's Agg backend;
    at most 300 s."""
    return subprocess.run(
        [sys.executable, "-m", "studies", *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "MPLBACKEND": "Agg", **(env or {})},
    )


def studies_main(argv: list[str]) -> int:
    """``python -m studies ARGV`` in this process: its exit status."""
    return main(argv, commands=COMMANDS, prog="python -m studies", description=DESCRIPTION)
