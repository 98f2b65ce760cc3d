"""How long ``python -m ekfslam`` takes as a whole process: the wait a user has at the prompt.

Two commands are timed, each as a fresh interpreter (start-up, imports, the work, exit) with a
wall-clock timer around the subprocess, and the median of `repeats` runs is kept: ``--help``
(which must import no command module, no numpy, no numba) and ``run data/runs/octagon-2laps``
(a classroom replay: numba's cached kernels, one replay, the Table 1 row). The targets are issue
14's, on a warm machine; a busy shared machine misses them without the code being at fault.
"""

from __future__ import annotations

import statistics
import subprocess
import sys
import time
from pathlib import Path

#: Issue 14's targets for the median wall time of each command, s.
TARGETS_S = {"help": 0.3, "run": 0.7}
#: The run ``run`` replays, inside the benchmark's runs folder.
RUN = "octagon-2laps"


def time_command(argv: list[str], repeats: int, cwd: Path | None = None) -> float:
    """Median wall time (s) of `repeats` runs of ``python -m ekfslam ARGV``, output discarded."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "ekfslam", *argv],
            cwd=cwd,
            check=True,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def startup_times(repeats: int, runs_dir: Path | None) -> dict:
    """``{"startup_s": {"help": s, "run": s or None}, "startup_target_s": ..., ...}``.

    `run` is None when `runs_dir` is None or does not hold `RUN`.
    """
    run = None if runs_dir is None else runs_dir / RUN
    return {
        "startup_s": {
            "help": time_command(["--help"], repeats),
            "run": time_command(["run", str(run)], repeats) if run and run.is_dir() else None,
        },
        "startup_target_s": dict(TARGETS_S),
        "startup_repeats": repeats,
    }


def startup_lines(r: dict) -> list[str]:
    """The "startup" section of the benchmark's markdown table."""
    lines = [
        "",
        f"| startup (whole process, median of {r['startup_repeats']}) | wall time | target |",
        "|---|---:|---:|",
    ]
    labels = {"help": "python -m ekfslam --help", "run": f"python -m ekfslam run {RUN}"}
    for key, label in labels.items():
        s = r["startup_s"][key]
        shown = "–" if s is None else f"{s:.3f} s"
        lines.append(f"| `{label}` | {shown} | {r['startup_target_s'][key]:g} s |")
    return lines
