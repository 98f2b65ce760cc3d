"""Issue 39, done-when item 3: ``--noise fit`` on every robot of MRCLAM Datasets 1, 2, 4 and 7,
never worse than the default it starts from by more than 10%.

`measure_one` replays a robot as ``python -m ekfslam run DATASET --robot N --noise fit`` does
(`ekfslam.analysis.noise_fit.fit_from_default`: the rescued default, the fit started from it,
the one kept) and scores the default's map, the fit's own map and the kept one's (eq. 17,
aligned): ground truth enters the score only, never the choice. `table` prints one line a robot
(robot, default, fit, kept, ratio) and `summary` how many are within `TOLERANCE`.

    python -m studies noise-fit [--datasets D ...] [--jobs N] [--json]
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

from ekfslam.analysis.evaluation import summarize
from ekfslam.analysis.mrclam_tuning import load_robot
from ekfslam.analysis.noise_fit import fit_from_default
from ekfslam.analysis.parallel import run_tasks
from ekfslam.logs.mrclam.load import find_dataset
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import ReplayResult

DATASETS = (1, 2, 4, 7)
ROBOTS = (1, 2, 3, 4, 5)
#: The issue's bound: the kept map at most this many times the default's.
TOLERANCE = 1.10


def _error(run: RunLog, result: ReplayResult) -> float:
    a = summarize(run, result).alignment
    return math.nan if a is None else float(a.mean_error)


def measure_one(dataset: int, robot: int) -> dict:
    """One robot: the default's, the fit's and the kept replay's map error (m), which was kept
    and why, the fit's gain on the default's sightings, the seconds of the whole choice."""
    run = load_robot(str(find_dataset(dataset)), robot)
    began = time.perf_counter()
    choice = fit_from_default(run)
    seconds = time.perf_counter() - began
    default, fit = _error(run, choice.default.result), _error(run, choice.fit.result)
    kept = fit if choice.kept == "fit" else default
    return {
        "dataset": dataset,
        "robot": robot,
        "default": default,
        "fit": fit,
        "kept_error": kept,
        "ratio": kept / default,
        "kept": choice.kept,
        "reason": choice.reason,
        "gain": choice.gain.as_dict(),
        "default_verdict": choice.default.result.diagnosis.verdict,
        "fit_verdict": choice.fit.diagnosis.verdict,
        "seconds": seconds,
    }


def measure(jobs: int = 1, datasets: Sequence[int] = DATASETS) -> list[dict]:
    """`measure_one` on every robot of `datasets`, in that order."""
    return run_tasks(measure_one, [(d, r) for d in datasets for r in ROBOTS], jobs=jobs)


def table(rows: Sequence[dict]) -> str:
    """Markdown: one line a robot."""
    lines = [
        "| dataset | robot | default (m) | fit (m) | kept | kept / default | fit's gain on the "
        "default's sightings (per sighting) | verdicts default, fit | s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        g = r["gain"]
        gain = "-" if g["mean"] is None else f"{g['mean']:+.3f}"
        if g["standard_error"] is not None:
            gain += f" ± {g['standard_error']:.3f}"
        lines.append(
            f"| {r['dataset']} | {r['robot']} | {r['default']:.3f} | {r['fit']:.3f} | "
            f"{r['kept']} | {r['ratio']:.2f} | {gain} | {r['default_verdict']}, "
            f"{r['fit_verdict']} | {r['seconds']:.0f} |"
        )
    return "\n".join(lines)


def summary(rows: Sequence[dict]) -> str:
    held = sum(r["ratio"] <= TOLERANCE for r in rows)
    worst = max(rows, key=lambda r: r["ratio"])
    return (
        f"{held}/{len(rows)} robots with the kept map within {TOLERANCE:.2f}x the default's; "
        f"the fit kept on {sum(r['kept'] == 'fit' for r in rows)}; worst "
        f"{worst['ratio']:.2f}x (dataset {worst['dataset']} robot {worst['robot']})"
    )
