"""`python -m ekfslam ...` as a user runs it: a fresh interpreter, captured output, no window.

One helper for the test files that drive the command line (pytest puts ``tests/`` on the path).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def run_ekfslam(
    *args: str, cwd: Path = REPO, env: dict | None = None
) -> subprocess.CompletedProcess:
    """Run ``python -m ekfslam ARGS`` with matplotlib's Agg backend; at most 300 s."""
    return subprocess.run(
        [sys.executable, "-m", "ekfslam", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "MPLBACKEND": "Agg", **(env or {})},
    )
