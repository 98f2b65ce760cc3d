"""The benchmark's report: the markdown table of `benchmarks.bench.run_benchmarks`' result,
and the files ``bench.md`` and ``bench.json`` it is written to.

Measuring is `benchmarks.bench`'s; this module only formats (a missing figure is "–"). The
figure ``cost_vs_n.png`` is drawn by `benchmarks.figure.plot_costs`.
"""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks.association import association_lines
from benchmarks.bench import MRCLAM_ROBOT, RUNS
from benchmarks.loop import loop_table
from benchmarks.startup import startup_lines
from ekfslam.files import atomic_write_text


def _fmt(value: float | None, scale: float = 1.0, digits: int = 1) -> str:
    return "–" if value is None else f"{value * scale:,.{digits}f}"


def markdown_table(r: dict) -> str:
    """The results as markdown: replays, then per-step costs against n, then the summary."""
    m = r["machine"]
    lines = [
        f"ekfslam benchmark, {r['date']}, {m['cores']} cores (load {_fmt(m['load_average_1min'])}),"
        f" Python {m['python']}, numpy {m['numpy']}. Command: `{r['command']}`. Medians.",
        "",
        "| replay (compiled steps) | median | events | events/s |",
        "|---|---:|---:|---:|",
    ]
    for key, name in RUNS.items():
        ms, eps = r["replay_ms"][key], r["replay_events_per_s"][key]
        events = r.get("replay_events", {}).get(key)
        lines.append(
            f"| {name} | {_fmt(ms)} ms | {_fmt(events, digits=0)} | {_fmt(eps, digits=0)} |"
        )
    if r.get("python_octagon_ms") is not None:
        lines.append(
            f"| {RUNS['octagon']}, the steps as Python (a short run's default) | "
            f"{_fmt(r['python_octagon_ms'])} ms | | |"
        )
    note = r.get("mrclam_note")
    lines.append(
        f"| MRCLAM Dataset 7, robot {MRCLAM_ROBOT}{f' ({note})' if note else ''} | "
        f"{_fmt(r['mrclam_replay_s'], digits=3)} s | "
        f"{_fmt(r['mrclam_events'], digits=0)} | {_fmt(r['mrclam_events_per_s'], digits=0)} |"
    )
    loop = r.get("loop")
    if loop is not None:  # results written before the user's loop was timed here have none
        lines += ["", loop_table(loop), "", *_per_event_lines(r, loop)]
    lines += [
        "",
        "| n | predict (µs) | update (µs) | literal predict (ms) | literal update (ms) "
        "| update ratio |",
        "|---:|---:|---:|---:|---:|---:|",
    ]
    eff, lit = r["cost_s"]["efficient"], r["cost_s"]["literal"]
    for n in r["sizes"]:
        ratio = r["update_ratio_vs_literal"][n]
        lines.append(
            f"| {n} | {_fmt(eff['predict'][n], 1e6)} | {_fmt(eff['update'][n], 1e6)} | "
            f"{_fmt(lit['predict'][n], 1e3, 2)} | {_fmt(lit['update'][n], 1e3, 2)} | "
            f"{'–' if ratio is None else f'{ratio:,.0f}x'} |"
        )
    lo, hi = r["update_slope_between"]
    fej = r["fej_step"]
    lines += [
        "",
        f"- efficient update, log-log slope n = {lo} to {hi}: "
        f"{_fmt(r['update_slope_100_1000'], digits=2)}",
        f"- update at n = {hi} / floor (one in-place `Sigma -= A @ B`, rank 2, same size, "
        f"{_fmt(r['floor_s'], 1e3, 2)} ms): {_fmt(r['update_vs_floor_1000'], digits=2)}x; "
        f"one pass `Sigma *= 1.0` takes {_fmt(r['inplace_pass_s'], 1e3, 2)} ms",
        f"- peak memory of the n = {hi} run ({r['peak_memory_method']}): "
        f"{_fmt(r['peak_mb_1000'])} MB",
        f"- FEJ / standard: octagon replay "
        f"{_fmt(r['fej_vs_standard']['replay_octagon'], digits=2)}x, "
        f"predict {_fmt(fej.get('predict'), digits=2)}x and update "
        f"{_fmt(fej.get('update'), digits=2)}x at n = {fej.get('update_n')}",
    ]
    inv = r.get("invariant_step")
    if inv is not None:  # results written before the invariant EKF have none
        lines.append(
            f"- invariant / standard: octagon replay "
            f"{_fmt(r['invariant_vs_standard']['replay_octagon'], digits=2)}x, "
            f"predict {_fmt(inv.get('predict'), digits=2)}x, update "
            f"{_fmt(inv.get('update'), digits=2)}x and predict + update "
            f"{_fmt(inv.get('step'), digits=2)}x at n = {inv.get('update_n')}"
        )
    it = r.get("iterated_step")
    if it:  # results written before the iterated update have none
        lines.append(
            f"- iterated (3 linearisations) / invariant: octagon replay "
            f"{_fmt(r['iterated_vs_invariant']['replay_octagon'], digits=2)}x, update "
            f"{_fmt(it.get('update'), digits=2)}x and predict + update "
            f"{_fmt(it.get('step'), digits=2)}x at n = {it.get('update_n')} "
            f"({_fmt(it.get('step_vs_standard'), digits=2)}x the standard step)"
        )
    lines += association_lines(r)
    if "startup_s" in r:  # results written before the startup section have none
        lines += startup_lines(r)
    return "\n".join(lines)


def _per_event_lines(r: dict, loop: dict) -> list[str]:
    """The user's loop against the replays, per event (a prediction or a sighting)."""
    per_event = loop["us_per_step"]["ekfslam default"] / loop["events_per_step"]
    replays = [
        f"{name} {_fmt(1e6 / r['replay_events_per_s'][key], digits=2)}"
        for key, name in RUNS.items()
        if r["replay_events_per_s"][key] is not None
    ]
    if r.get("mrclam_events_per_s"):
        replays.append(f"MRCLAM robot {MRCLAM_ROBOT} {1e6 / r['mrclam_events_per_s']:.2f}")
    return [
        f"- µs per event: the user's loop (default config, its own Python around each call) "
        f"{per_event:.2f}; the replays {', '.join(replays) or '–'}"
    ]


def write_outputs(r: dict, out: Path) -> None:
    # each file is renamed into place when complete: a failed run keeps the previous outputs;
    # the figure is the caller's to draw (`benchmarks.figure.plot_costs`): analysis draws none
    atomic_write_text(out / "bench.md", markdown_table(r) + "\n")
    atomic_write_text(out / "bench.json", json.dumps(r, indent=2, allow_nan=False) + "\n")
