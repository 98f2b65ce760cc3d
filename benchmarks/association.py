"""What association costs (issue 16): replays with ids hidden, and one JCBB step against m.

Part of ``python -m benchmarks bench`` (`benchmarks.bench`):

- the octagon replayed with ``known``, ``nn``, ``jcbb`` and ``mht`` association, interleaved:
  the median time per sighting (µs) and each one's ratio to known;
- one association decision against the number m of sightings taken at one time: the NN choice
  (compiled, `ekfslam.core.filter.nearest.nearest`), the JCBB decision the filter makes
  (compiled, `ekfslam.core.filter.jcbb_kernels`) and its readable numpy form
  (`AssociatingFilter.predicted`, `ekfslam.core.association.jcbb`), over a map of `MAP_SIZE`
  landmarks on a circle the robot sits in, its pose uncertain (`POSE_SIGMA`), each sighting
  noisy; the JCBB nodes and whether the budget was hit.
"""

from __future__ import annotations

import math
import statistics
import time
from pathlib import Path

import numpy as np

from benchmarks.timing import median_time
from ekfslam.core.association import AssociationConfig, jcbb
from ekfslam.core.filter.associating import AssociatingFilter
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.models import observation, observation_noise
from ekfslam.logs.runlog import read_run
from ekfslam.pipeline import replay

METHODS = ("known", "nn", "jcbb", "mht")  # mht: the bank at its default size
SIGHTINGS = (1, 2, 4, 8, 16)  # m, sightings at one time
MAP_SIZE = 16  # landmarks
POSE_SIGMA = (0.05, 0.05, 0.02)  # m, m, rad: a robot some way into a loop
_Q = observation_noise(0.05, 0.03)
#: the filter's steps compiled, as a long run's are: the figures compare with `bench`'s replays
COMPILED = FilterConfig(backend="numba")


def bench_association(runs_dir: Path | None, repeats: int) -> dict:
    """``association_replay_us_per_sighting``, ``association_vs_known`` and
    ``association_step_ms`` (per m: nn, jcbb, jcbb_numpy, jcbb_nodes, budget_hit); replay
    figures are None without the seed's runs."""
    out: dict = {"association_replay_us_per_sighting": dict.fromkeys(METHODS)}
    out["association_vs_known"] = dict.fromkeys(METHODS[1:])
    folder = None if runs_dir is None else runs_dir / "octagon-2laps"
    if folder is not None and folder.is_dir():
        run = read_run(folder)
        configs = {m: AssociationConfig(method=m) for m in METHODS}
        times: dict[str, list[float]] = {m: [] for m in METHODS}
        for _ in range(repeats):  # interleaved, as the other replays
            for m, c in configs.items():
                t0 = time.perf_counter()
                replay(run, config=COMPILED, association=c)
                times[m].append(time.perf_counter() - t0)
        n = len(run.detections.t)
        per = {m: 1e6 * statistics.median(times[m]) / n for m in METHODS}
        out["association_replay_us_per_sighting"] = per
        out["association_vs_known"] = {m: per[m] / per["known"] for m in METHODS[1:]}
    out["association_step_ms"] = {str(m): _step(m, repeats) for m in SIGHTINGS}
    out["association_map_size"] = MAP_SIZE
    return out


def _step(m: int, repeats: int) -> dict:
    """One decision for m sightings among `MAP_SIZE` landmarks: NN and JCBB, median ms."""
    rng = np.random.default_rng(m)
    angles = np.linspace(0.0, 2.0 * math.pi, MAP_SIZE, endpoint=False)
    landmarks = 2.0 * np.column_stack([np.cos(angles), np.sin(angles)])
    f = EKFSLAM(np.zeros(3), np.diag(np.square(POSE_SIGMA)), COMPILED)
    for j, p in enumerate(landmarks):
        f.update(j, observation(np.zeros(3), p), _Q)
    truth = np.array([0.03, -0.02, 0.01])  # where the robot really is
    seen = rng.choice(MAP_SIZE, size=m, replace=False)
    zs = np.array([observation(truth, landmarks[j]) for j in seen])
    zs += rng.normal(0.0, np.sqrt(np.diag(_Q)), size=zs.shape)
    a = AssociatingFilter(f, AssociationConfig(method="jcbb"))
    Qs = np.broadcast_to(_Q, (m, 2, 2))
    cfg = a.config

    def nn() -> object:  # what `AssociatingFilter.observe` runs for nn: the compiled kernel
        return a._nearest(zs, _Q)

    def joint() -> object:  # what `AssociatingFilter.observe` runs for jcbb: compiled
        return a._jcbb(zs, _Q)

    def reference() -> object:  # the readable numpy form it decides as
        nu, P = a.predicted(zs)
        return jcbb(nu, P, Qs, cfg.gate, cfg.joint_probability, cfg.node_budget)

    found = reference()
    return {
        "nn": 1e3 * median_time(nn, repeats),
        "jcbb": 1e3 * median_time(joint, repeats),
        "jcbb_numpy": 1e3 * median_time(reference, repeats),
        "jcbb_nodes": found.nodes,
        "budget_hit": found.budget_hit,
        "jcbb_correct": bool((found.pairing == seen).all()),
    }


def association_lines(r: dict) -> list[str]:
    """The bench table's association rows (markdown)."""
    if "association_step_ms" not in r:  # results written before this section have none
        return []
    per, vs = r["association_replay_us_per_sighting"], r["association_vs_known"]

    def fmt(x, digits=1):
        return "–" if x is None else f"{x:.{digits}f}"

    lines = [
        "",
        "| association, octagon replay | known | nn | jcbb | mht |",
        "|---|---:|---:|---:|---:|",
        f"| µs per sighting | {fmt(per['known'])} | {fmt(per['nn'])} | {fmt(per['jcbb'])} "
        f"| {fmt(per.get('mht'))} |",  # older results have no mht
        f"| / known | 1 | {fmt(vs['nn'], 2)}x | {fmt(vs['jcbb'], 2)}x | {fmt(vs.get('mht'), 2)}x |",
        "",
        f"| sightings at one time ({r['association_map_size']} landmarks) | nn (ms) | jcbb (ms) "
        "| jcbb, numpy form (ms) | jcbb nodes | budget hit | jcbb right |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for m, s in r["association_step_ms"].items():
        lines.append(
            f"| {m} | {fmt(s['nn'], 3)} | {fmt(s['jcbb'], 3)} | {fmt(s.get('jcbb_numpy'), 3)} "
            f"| {s['jcbb_nodes']} | "
            f"{'yes' if s['budget_hit'] else 'no'} | {'yes' if s['jcbb_correct'] else 'no'} |"
        )
    return lines
