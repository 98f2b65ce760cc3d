"""A classroom on one machine: memory per Voila session and latency with several students at once.

`classroom_benchmark` serves the seed-run panel from one Voila server on 127.0.0.1 and opens
1, 2, ... `max_sessions` headless Chromium pages on it (each page is a session: its own kernel).
At each count it records the resident memory (RSS) of every kernel and of the server, then moves
the σr slider on every page together (`benchmarks.browser.measure_together`) and takes the
median and p90 of the key press to new pixels over all pages' moves. A count holds the seed-run
target of issue 18 when the median is at most `TARGET_MEDIAN_MS` and the p90 at most
`TARGET_P90_MS`. The browsers run on the same machine as the kernels (in a classroom they run on
the students' machines), so the figures are a bound from below on how many sessions it serves.
``python -m benchmarks tune --classroom N`` prints it.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.browser import (
    CHROMIUM,
    CHROMIUM_ARGS,
    measure_together,
    open_panel,
    panel_notebook,
    voila_server,
)

#: The seed-run targets of issue 18 (ms), measured in the browser.
TARGET_MEDIAN_MS, TARGET_P90_MS = 50.0, 80.0
#: Pages that are not in front must not be throttled: every student's page is in front.
NO_THROTTLING = (
    "--disable-renderer-backgrounding --disable-background-timer-throttling "
    "--disable-backgrounding-occluded-windows"
).split()


def rss_mb(pid: int) -> float:
    """Resident memory of process `pid` in MiB (from /proc; 0 when it is gone)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return 0.0
    for line in status.splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


def children(pid: int) -> list[int]:
    """Pids of the live direct children of `pid` (Voila's kernels are its children)."""
    found = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            try:
                stat = (proc / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:  # field 4, after "(comm)"
                found.append(int(proc.name))
    return sorted(found)


def session_row(sessions: int, latencies_ms, kernels_mb, server_mb: float) -> dict:
    """One count's figures: latency median/p90 (ms) over all moves, RSS per kernel (MiB)."""
    ms = np.asarray(latencies_ms, dtype=float)
    median, p90 = float(np.median(ms)), float(np.percentile(ms, 90))
    return {
        "sessions": sessions,
        "median_ms": median,
        "p90_ms": p90,
        "moves": int(ms.size),
        "kernel_rss_mb": [float(m) for m in kernels_mb],
        "server_rss_mb": float(server_mb),
        "holds_target": median <= TARGET_MEDIAN_MS and p90 <= TARGET_P90_MS,
    }


def sessions_holding_target(rows: list[dict]) -> int:
    """The largest count of sessions that held the target, all smaller counts holding it too."""
    held = 0
    for row in sorted(rows, key=lambda r: r["sessions"]):
        if not row["holds_target"]:
            break
        held = row["sessions"]
    return held


def classroom_benchmark(max_sessions: int = 4, moves: int = 10, setup: str | None = None):
    """Rows of `session_row` for 1 .. `max_sessions` concurrent seed-run panels on one server.

    setup : the notebook cell that defines ``panel`` (default: the seed runs' panel).
    Every count is measured (no early stop), so the table shows how the latency grows; each
    count's pages are the previous count's plus one new session.
    """
    from playwright.sync_api import sync_playwright  # lazy: a test-only dependency

    setup = setup or "panel = tuning_panel()"
    rows = []
    with tempfile.TemporaryDirectory(prefix="ekfslam-classroom-") as tmp_name:
        tmp = Path(tmp_name)
        folder = tmp / "notebooks"
        folder.mkdir()
        (folder / "panel.ipynb").write_text(json.dumps(panel_notebook(setup)))
        with voila_server(folder, tmp) as (base, token, pid), sync_playwright() as p:
            args = [*CHROMIUM_ARGS, *NO_THROTTLING]
            browser = p.chromium.launch(executable_path=str(CHROMIUM), args=args)
            pages = []
            for n in range(1, max_sessions + 1):
                pages.append(open_panel(browser, base, token, "panel"))
                time.sleep(1.0)  # the new kernel settles
                kernels = [rss_mb(k) for k in children(pid)]
                moved = measure_together(pages, moves)
                latencies = [m.latency_ms for page_moves in moved for m in page_moves]
                changed = sum(m.changed for page_moves in moved for m in page_moves)
                row = session_row(n, latencies, kernels, rss_mb(pid))
                rows.append({**row, "changed": changed})
            for page in pages:
                page.close(run_before_unload=True)
            browser.close()
    return rows
