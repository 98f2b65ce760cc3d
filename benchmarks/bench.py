"""Benchmarks: a replay at classroom scale, and the cost of one step against the map size n.

``python -m benchmarks bench [--quick] [--json] [--out DIR]`` measures, in one run:

- full replays of ``data/runs/octagon-2laps`` and ``square-2laps`` (ms, filter events per second),
  the octagon also with ``FilterConfig(linearization="fej")`` and ``"invariant"`` (their cost
  relative to standard; the invariant EKF's prediction is O(n²), its noise reaching the map),
  and the invariant EKF with the iterated update (`ITERATED`) relative to the plain invariant one;
- one `EKFSLAM.predict` and one `EKFSLAM.update` against n in `SIZES`, for the efficient filter
  and the literal F_x reference (`ekfslam.teaching.reference`, O(n^3): skipped, reported as null,
  where one step would take more than `LITERAL_MAX_STEP_S`), their ratio, the log-log slope of the
  efficient update between n = 100 and 1000, and the update at n = 1000 against the memory-bound
  floor: one in-place ``Sigma -= A @ B`` of the same rank (2) on an array of the same size;
- the peak memory of the n = 1000 run (tracemalloc: numpy buffers and Python objects);
- a full replay of one MRCLAM Dataset 7 robot, when the shared data folder has it;
- a user's own loop of the step API (`EKFSLAM.predict_many`, `update`, `pose`,
  `pose_covariance` every step) on ukfm's 2D SLAM world against ukfm's and PythonRobotics' loops
  (`benchmarks.loop`), per step and per event beside the replays' events;
- association with the ids hidden: the octagon with nn and jcbb against known, and one decision
  against the number of sightings at one time (`benchmarks.association`).

Every figure is a median over repeats; replays are interleaved so that a busy machine slows all
of them alike. Machines are shared and noisy: compare figures from one run. The results go to
``DIR/bench.md`` (the table, `benchmarks.report`), ``DIR/bench.json`` and
``DIR/cost_vs_n.png`` (log-log plot, `benchmarks.figure`).
"""

from __future__ import annotations

import datetime
import math
import os
import platform
import statistics
import time
import tracemalloc
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from benchmarks.association import bench_association
from benchmarks.loop import bench_loop
from benchmarks.startup import startup_times
from benchmarks.timing import median_time
from benchmarks.ukfm_slam2d import STEPS
from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.models import observation_noise
from ekfslam.core.noise import default_noise
from ekfslam.errors import ConfigError
from ekfslam.logs.mrclam.cache import mrclam_path
from ekfslam.logs.mrclam.load import load_mrclam
from ekfslam.logs.runlog import read_run
from ekfslam.pipeline import replay
from ekfslam.places import seed_runs_dir, shared_data_dir
from ekfslam.teaching.reference import LiteralEKFSLAM

SIZES = (10, 50, 100, 200, 400, 800, 1000)
#: Largest map size: Σ of a 2000-landmark map is 4003² float64, 128 MB, and one literal step
#: would take minutes; beyond that a benchmark measures the swap file.
MAX_SIZE = 2000
#: The literal reference is skipped at sizes where one step is predicted to take longer (s).
LITERAL_MAX_STEP_S = 2.0
RUNS = {"octagon": "octagon-2laps", "square": "square-2laps"}
MRCLAM_ROBOT = 1
#: the iterated update measured against the plain invariant EKF (`FilterConfig.iterations`)
#: The replays and steps measured run compiled (`FilterConfig.backend`); the octagon is also
#: replayed with the steps as Python, what a short run gets by default.
COMPILED = FilterConfig(backend="numba")
ITERATED = FilterConfig(linearization="invariant", iterations=3, backend="numba")


#: The repeat counts of `BenchConfig` (``--repeats`` sets them all).
REPEATS = (
    "replay_repeats",
    "step_repeats",
    "literal_repeats",
    "mrclam_repeats",
    "startup_repeats",
    "loop_runs",
)


@dataclass(frozen=True)
class BenchConfig:
    """What to measure and how often (`quick` is the ``--quick`` preset)."""

    sizes: tuple[int, ...] = SIZES
    replay_repeats: int = 21
    step_repeats: int = 41
    literal_repeats: int = 3
    mrclam_repeats: int = 3
    #: whole-process runs of ``--help`` and ``run`` (`benchmarks.startup`)
    startup_repeats: int = 5
    #: worlds of the user's loop (`benchmarks.loop`), and the steps of each
    loop_runs: int = 5
    loop_steps: int = STEPS
    #: the seed's runs (default: the source checkout's data/runs; None when installed)
    runs_dir: Path | None = field(default_factory=seed_runs_dir)
    mrclam_dir: Path | None = None
    #: why there is no `mrclam_dir`, printed in the MRCLAM row (default `MRCLAM_MISSING`)
    mrclam_note: str | None = None

    def __post_init__(self) -> None:
        sizes = self.sizes
        if not sizes or not all(isinstance(n, int) and not isinstance(n, bool) for n in sizes):
            raise ConfigError(f"BenchConfig.sizes must be whole numbers, got {sizes!r}")
        if not all(1 <= n <= MAX_SIZE for n in sizes):
            raise ConfigError(f"BenchConfig.sizes must be in 1..{MAX_SIZE}, got {sizes!r}")
        if isinstance(self.loop_steps, bool) or not isinstance(self.loop_steps, int):
            raise ConfigError(
                f"BenchConfig.loop_steps must be a whole number, got {self.loop_steps!r}"
            )
        if self.loop_steps < 2:
            raise ConfigError(f"BenchConfig.loop_steps must be >= 2, got {self.loop_steps!r}")
        for name in REPEATS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f"BenchConfig.{name} must be a whole number >= 1, got {value!r}")

    @classmethod
    def quick(cls, **kwargs) -> BenchConfig:
        base = dict(
            replay_repeats=7,
            step_repeats=15,
            literal_repeats=1,
            mrclam_repeats=1,
            startup_repeats=3,
            loop_runs=3,
        )
        return cls(**{**base, **kwargs})


#: Why the MRCLAM row is empty when no dataset folder was given or found, and how to fill it.
MRCLAM_MISSING = (
    "not run: MRCLAM Dataset 7 not found in the shared data or the fetch cache; "
    "`python -m ekfslam fetch mrclam 7` downloads it"
)
MRCLAM_SKIPPED = "not run: --no-mrclam"


def default_mrclam_dir() -> Path | None:
    """MRCLAM Dataset 7 in the shared data folder (`ekfslam.places.shared_data_dir`), else
    where ``python -m ekfslam fetch mrclam 7`` puts it, or None."""
    shared = shared_data_dir()
    places = [shared / "mrclam" / "MRCLAM_Dataset7"] if shared is not None else []
    for path in (*places, mrclam_path(7)):
        if path.is_dir():
            return path
    return None


# ------------------------------------------------------------------------------------ replays
def bench_replays(config: BenchConfig) -> dict:
    """Median replay times of the seed's runs (ms), events/s, and FEJ's cost on the octagon."""
    out: dict = {
        "replay_ms": {},
        "replay_events_per_s": {},
        "fej_vs_standard": {},
        "invariant_vs_standard": {},
        "iterated_vs_invariant": {},
    }
    folder = config.runs_dir
    if folder is None or not all((folder / name).is_dir() for name in RUNS.values()):
        for key in RUNS:
            out["replay_ms"][key] = out["replay_events_per_s"][key] = None
        out["fej_vs_standard"]["replay_octagon"] = None
        out["invariant_vs_standard"]["replay_octagon"] = None
        out["iterated_vs_invariant"]["replay_octagon"] = None
        return out
    runs = {key: read_run(folder / name) for key, name in RUNS.items()}
    cases = {key: (run, COMPILED) for key, run in runs.items()}
    for lin in ("fej", "invariant"):
        cases[lin] = (runs["octagon"], replace(COMPILED, linearization=lin))
    cases["iterated"] = (runs["octagon"], ITERATED)
    events = {key: len(replay(run, config=c).history.t) for key, (run, c) in cases.items()}
    times: dict[str, list[float]] = {key: [] for key in [*cases, "python"]}
    for _ in range(config.replay_repeats):  # interleaved: a busy spell hits every case alike
        for key, (run, filter_config) in cases.items():
            t0 = time.perf_counter()
            replay(run, config=filter_config)
            times[key].append(time.perf_counter() - t0)
    # the steps as Python on their own: between the compiled replays, each of these 150 ms
    # replays left them running cold (the octagon measured 15 ms interleaved, 9 ms alone)
    as_python = replace(COMPILED, backend="python")
    for _ in range(config.replay_repeats):
        t0 = time.perf_counter()
        replay(runs["octagon"], config=as_python)
        times["python"].append(time.perf_counter() - t0)
    for key in runs:
        s = statistics.median(times[key])
        out["replay_ms"][key] = 1e3 * s
        out["replay_events_per_s"][key] = events[key] / s
    out["replay_events"] = {key: events[key] for key in runs}
    for lin in ("fej", "invariant"):
        out[f"{lin}_vs_standard"]["replay_octagon"] = statistics.median(
            times[lin]
        ) / statistics.median(times["octagon"])
    out["iterated_vs_invariant"]["replay_octagon"] = statistics.median(
        times["iterated"]
    ) / statistics.median(times["invariant"])
    out["python_octagon_ms"] = 1e3 * statistics.median(times["python"])
    return out


def bench_mrclam(config: BenchConfig) -> dict:
    """Median replay time (s) of one MRCLAM Dataset 7 robot, or None without the data."""
    folder = config.mrclam_dir
    if folder is None:
        note = config.mrclam_note or MRCLAM_MISSING
        return {
            "mrclam_replay_s": None,
            "mrclam_events_per_s": None,
            "mrclam_events": None,
            "mrclam_note": note,
        }
    run, _ = load_mrclam(folder, MRCLAM_ROBOT)
    noise = default_noise(run)
    events = len(replay(run, noise).history.t)
    s = median_time(lambda: replay(run, noise), config.mrclam_repeats)
    return {
        "mrclam_replay_s": s,
        "mrclam_events_per_s": events / s,
        "mrclam_events": events,
        "mrclam_note": None,
    }


# --------------------------------------------------------------------------- cost against n
_Q = observation_noise(0.05, 0.03)
_R = np.diag([1e-4, 1e-4, 1e-5])
_U = (0.02, 0.005, 0.01)


def map_of(n: int, config: FilterConfig | None = None, record: bool = False, seed: int = 0):
    """An `EKFSLAM` that has met n landmarks (on a ring 1-5 m around it), and its observations.

    Returns the filter and a list of (id, z) to update with: each landmark as seen from the
    filter's pose, so every update is accepted and leaves the geometry alone.
    """
    rng = np.random.default_rng(seed)
    config = config or FilterConfig(gate=None, backend="numba")
    f = EKFSLAM([0.0, 0.0, 0.0], np.diag([1e-4, 1e-4, 1e-5]), config, record=record)
    zs = [(j, (rng.uniform(1.0, 5.0), rng.uniform(-math.pi, math.pi))) for j in range(n)]
    for j, z in zs:
        f.update(j, z, _Q)
    f.predict(_U, _R)  # correlate the pose with the map, as any real run has
    return f, zs


def literal_twin(f: EKFSLAM) -> LiteralEKFSLAM:
    """The literal reference in the same state as `f` (`LiteralEKFSLAM.from_state`)."""
    own = f.invariant_covariance if f.config.linearization == "invariant" else f.Sigma.copy()
    return LiteralEKFSLAM.from_state(f.mu, own, f.landmark_ids, f.config)


def _step_costs(filters: list, zs, repeats: int) -> list[tuple[float, float]]:
    """Median seconds of one predict and one update of each filter, timed in turn.

    Updates cycle through the landmarks. Interleaving puts a busy spell of a shared machine on
    every filter alike, so their ratio stays fair.
    """
    times = [([], []) for _ in filters]
    for k in range(repeats):
        j, z = zs[k % len(zs)]
        for f, (predict, update) in zip(filters, times, strict=True):
            t0 = time.perf_counter()
            f.predict(_U, _R)
            t1 = time.perf_counter()
            f.update(j, z, _Q)
            update.append(time.perf_counter() - t1)
            predict.append(t1 - t0)
    return [(statistics.median(p), statistics.median(u)) for p, u in times]


def bench_sizes(config: BenchConfig) -> dict:
    """Per-step costs against n for both implementations, the slope, the floor, FEJ's cost."""
    eff: dict = {"predict": {}, "update": {}}
    lit: dict = {"predict": {}, "update": {}}
    last = None  # (d, seconds) of the latest literal step, to predict the next one's cost
    fej, inv, iterated = {}, {}, {}
    # (100, 1000) when measured, else the smallest and largest size (a tiny smoke run)
    lo = 100 if 100 in config.sizes else min(config.sizes)
    hi = 1000 if 1000 in config.sizes else max(config.sizes)
    for n in config.sizes:
        f, zs = map_of(n)
        if n == lo:
            g, _ = map_of(n, replace(COMPILED, gate=None, linearization="fej"))
            h, _ = map_of(n, replace(COMPILED, gate=None, linearization="invariant"))
            k, _ = map_of(n, replace(ITERATED, gate=None))
            (p, u), (pg, ug), (ph, uh), (pk, uk) = _step_costs(
                [f, g, h, k], zs, config.step_repeats
            )
            fej = {"update_n": n, "predict": pg / p, "update": ug / u}
            inv = {"update_n": n, "predict": ph / p, "update": uh / u, "step": (ph + uh) / (p + u)}
            iterated = {
                "update_n": n,
                "update": uk / uh,
                "step": (pk + uk) / (ph + uh),
                "step_vs_standard": (pk + uk) / (p + u),
            }
        else:
            [(p, u)] = _step_costs([f], zs, config.step_repeats)
        eff["predict"][n], eff["update"][n] = p, u
        d = 3 + 2 * n
        if last is not None and _literal_too_slow(*last, d):
            lit["predict"][n] = lit["update"][n] = None
            continue
        repeats = config.literal_repeats if n > 100 else config.step_repeats
        [(p, u)] = _step_costs([literal_twin(f)], zs, repeats)
        lit["predict"][n], lit["update"][n] = p, u
        last = (d, max(p, u))
    slope = math.log(eff["update"][hi] / eff["update"][lo]) / math.log(hi / lo) if hi > lo else None
    floor, one_pass = floor_times(hi, config.step_repeats)
    return {
        "sizes": list(config.sizes),
        "cost_s": {"efficient": eff, "literal": lit},
        "update_ratio_vs_literal": {
            n: None if lit["update"][n] is None else lit["update"][n] / eff["update"][n]
            for n in config.sizes
        },
        "update_slope_100_1000": slope,
        "update_slope_between": [lo, hi],
        "update_vs_floor_1000": eff["update"][hi] / floor,
        "floor_n": hi,
        "floor_s": floor,
        "inplace_pass_s": one_pass,
        "fej_step": fej,
        "invariant_step": inv,
        "iterated_step": iterated,
    }


def _literal_too_slow(d_measured: int, seconds: float, d: int) -> bool:
    """Would one literal step at dimension d exceed `LITERAL_MAX_STEP_S`?

    Extrapolated as d^3 from the last measured step once that took 50 ms (below, fixed costs
    hide the cubic term and the extrapolation would be far too pessimistic).
    """
    if seconds > LITERAL_MAX_STEP_S:
        return True
    return seconds >= 0.05 and seconds * (d / d_measured) ** 3 > LITERAL_MAX_STEP_S


def floor_times(n: int, repeats: int) -> tuple[float, float]:
    """Median seconds of one ``Sigma -= A @ B`` (rank 2; the issue's floor) and of one in-place
    pass ``Sigma *= 1.0`` (reads and writes Σ once, no temporary), Sigma (3 + 2n) square."""
    d = 3 + 2 * n
    rng = np.random.default_rng(1)
    Sigma = rng.standard_normal((d, d))
    A, B = rng.standard_normal((d, 2)), rng.standard_normal((2, d))

    def floor():
        nonlocal Sigma
        Sigma -= A @ B

    def one_pass():
        nonlocal Sigma
        Sigma *= 1.0

    return median_time(floor, repeats), median_time(one_pass, repeats)


def peak_memory_mb(n: int, steps: int = 50) -> float:
    """Peak traced memory (MB, 10^6 bytes) of building an n-landmark map and stepping it.

    tracemalloc sees numpy's buffers and Python's objects; the filter records its history.
    """
    tracemalloc.start()
    try:
        f, zs = map_of(n, record=True)
        for k in range(steps):
            f.predict(_U, _R)
            f.update(*zs[k % len(zs)], _Q)
        f.history()
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


# ------------------------------------------------------------------------------- the results
def run_benchmarks(config: BenchConfig, command: str = "python -m benchmarks bench") -> dict:
    """Everything above, with the date, the machine and the command: a JSON-ready dict."""
    result = {
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "command": command,
        "machine": {
            "cores": os.cpu_count(),
            "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
            "python": platform.python_version(),
            "numpy": np.__version__,
            "platform": platform.platform(),
        },
    }
    result.update(bench_replays(config))
    result.update(bench_mrclam(config))
    result["loop"] = bench_loop(config.loop_runs, config.loop_steps)
    result.update(bench_association(config.runs_dir, config.replay_repeats))
    result.update(bench_sizes(config))
    result["peak_mb_1000"] = peak_memory_mb(result["floor_n"])
    result["peak_memory_method"] = "tracemalloc"
    result.update(startup_times(config.startup_repeats, config.runs_dir))
    return result
