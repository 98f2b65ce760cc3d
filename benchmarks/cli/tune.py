"""``python -m benchmarks tune --bench|--browser|--classroom N [--repeats N] [--json]``: latency.

The panel itself lives in a notebook (`ekfslam.ui.widgets.tuning_panel`); ``--bench`` times what
one slider change costs in this process, from the change to the redrawn figure, on each seed run;
``--browser`` times a key press to the figure's new pixels in headless Chromium (Voila on
127.0.0.1), the panel as it draws today and as it drew before blitting, alternately;
``--classroom N`` serves 1 .. N seed-run sessions from one Voila server at once and prints each
kernel's memory and the latency with every student moving a slider together.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from benchmarks.browser import browser_benchmark
from benchmarks.classroom import (
    TARGET_MEDIAN_MS,
    TARGET_P90_MS,
    classroom_benchmark,
    sessions_holding_target,
)
from benchmarks.panel import benchmark
from ekfslam.cli import args as ca
from ekfslam.errors import InputError
from ekfslam.logs.mrclam.load import find_dataset

#: The panel as it was before blitting (issue 18): a full draw per move through ipympl's draw
#: request, and a change waiting COALESCE_DELAY even after an idle spell.
BEFORE = (
    "import asyncio\nfrom ekfslam.ui.coalescer import COALESCE_DELAY\n"
    "panel = tuning_panel({runs}blit=False)\n"
    "panel.tuner._coalescer._schedule = "
    "lambda fn: asyncio.get_running_loop().call_later(COALESCE_DELAY, fn)"
)
AFTER = "panel = tuning_panel({runs})"
MRCLAM_RUNS = (
    "from ekfslam.logs.mrclam.load import load_mrclam\n"
    "runs = {{'mrclam7-r1': lambda: load_mrclam({folder!r}, 1)[0]}}\n"
)


def add_command(subparsers: argparse._SubParsersAction, name: str, help: str) -> None:
    """Register ``tune`` (`help` is the one line of `benchmarks.__main__.COMMANDS`)."""
    p = subparsers.add_parser(name, help=help, description=__doc__.split("\n\n")[0])
    p.add_argument("--bench", action="store_true", help="time the panel's update")
    p.add_argument(
        "--browser",
        action="store_true",
        help="time key press to new pixels in headless Chromium (Voila)",
    )
    p.add_argument(
        "--against",
        type=Path,
        metavar="DIR",
        help="with --browser: the panel also from another checkout DIR (its "
        "ekfslam/), alternately; e.g. main against a branch",
    )
    p.add_argument(
        "--classroom",
        type=ca.whole(1, 12, why="one machine"),
        metavar="N",
        help="1 .. N concurrent Voila sessions: memory and latency",
    )
    p.add_argument(
        "--repeats",
        type=ca.whole(1, 1000),
        default=None,
        help="samples per run (default: 15, in the browser 20 moves)",
    )
    ca.add_json_argument(p)
    p.set_defaults(func=cmd_tune, print_help=p.print_help)


def cmd_tune(args: argparse.Namespace) -> int:
    if args.browser:
        return _browser(args)
    if args.classroom:
        return _classroom(args)
    if not args.bench:
        args.print_help()
        return 0
    results = benchmark(repeats=args.repeats or 15)
    if args.json:
        print(json.dumps(results, indent=2, allow_nan=False))
        return 0
    for name, r in results.items():
        print(
            f"{name:<16} median {r['median_ms']:6.1f} ms = replay {r['replay_ms']:.1f} ms "
            f"+ summary and artists {r['update_ms'] - r['replay_ms']:.1f} ms "
            f"+ render to PNG {r['draw_ms']:.1f} ms; CPU time {r['cpu_ms']:.1f} ms "
            f"({r['samples']} samples; target 100 ms); blitted as on ipympl "
            f"{r['blit_ms']:.1f} ms, of which the frame (diff and PNG, "
            f"{r['frame_kib']:.0f} KiB) {r['frame_ms']:.1f} ms"
        )
    return 0


def _browser(args: argparse.Namespace) -> int:
    against = args.against
    if against is not None and not (against / "ekfslam" / "__init__.py").is_file():
        raise InputError(against, None, "not a checkout of ekfslam (no ekfslam/__init__.py)")
    if against is None:
        setups = {"seed, before": BEFORE.format(runs=""), "seed, now": AFTER.format(runs="")}
    else:  # this checkout's panel against the other's, as each draws it
        setups = {"seed": AFTER.format(runs="")}
    try:  # dataset 7: the one with the robots' true paths (the figure's grey line)
        code = MRCLAM_RUNS.format(folder=str(find_dataset(7)))
    except InputError as exc:
        print(f"(no MRCLAM robot: {exc})")
    else:
        if against is None:
            setups["MRCLAM 7 robot 1, before"] = code + BEFORE.format(runs="runs, ")
            setups["MRCLAM 7 robot 1, now"] = code + AFTER.format(runs="runs, ")
        else:
            setups["MRCLAM 7 robot 1"] = code + AFTER.format(runs="runs, ")
    results = browser_benchmark(
        setups, moves=args.repeats or 20, rounds=2 if against is None else 4, against=against
    )
    if args.json:
        print(json.dumps(results, indent=2, allow_nan=False))
        return 0
    for name, r in results.items():
        print(
            f"{name:<26} key press to new pixels: median {r['median_ms']:6.1f} ms, "
            f"p90 {r['p90_ms']:6.1f} ms; figure changed {r['changed']}/{r['moves']} moves"
        )
        if r["pieces"]:
            print(f"{'':<26} where it went (medians, ms): " + _pieces(r["pieces"]))
    return 0


def _pieces(p: dict[str, float]) -> str:
    return (
        f"key to websocket {p['key_to_send']:.1f}, to the kernel's first reply "
        f"{p['send_to_reply']:.1f}, to the frame {p['reply_to_frame']:.1f} "
        f"({p['frame_kib']:.0f} KiB), to its blob {p['frame_to_blob']:.1f}, ipympl's "
        f"toDataURL {p['png_copy']:.1f}, blob loaded {p['blob_to_loaded']:.1f}, "
        f"painted {p['loaded_to_painted']:.1f}"
    )


def _classroom(args: argparse.Namespace) -> int:
    rows = classroom_benchmark(args.classroom, moves=args.repeats or 10)
    held = sessions_holding_target(rows)
    if args.json:
        print(json.dumps({"sessions": rows, "holding_target": held}, indent=2, allow_nan=False))
        return 0
    for r in rows:
        kernels = r["kernel_rss_mb"]
        print(
            f"{r['sessions']:2d} sessions: key press to new pixels median {r['median_ms']:6.1f} "
            f"ms, p90 {r['p90_ms']:6.1f} ms over {r['moves']} moves (changed {r['changed']}); "
            f"kernel RSS {np.median(kernels):.0f} MiB each (max {max(kernels):.0f}), "
            f"server {r['server_rss_mb']:.0f} MiB; {'holds' if r['holds_target'] else 'misses'}"
            f" the target"
        )
    print(
        f"sessions holding the seed-run target (median <= {TARGET_MEDIAN_MS:.0f} ms, "
        f"p90 <= {TARGET_P90_MS:.0f} ms): {held}"
    )
    return 0
