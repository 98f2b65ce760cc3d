"""Does the filter survive bad data and long runs? Outlier gating, and Σ over 10^5 steps.

`outlier_study` injects the simulator's outliers (wrong tag ids, gross ranges) into the
scenarios of `ekfslam.sim.scenarios` and compares the aligned map error (eq. 17) with
the clean run's, gate on and gate off; every rejection is counted. `long_run` drives the filter
for many steps around a ring of landmarks and checks that Σ stays finite, symmetric and positive
semi-definite (smallest eigenvalue >= -1e-9 · trace).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, fields

import numpy as np

from ekfslam.analysis.alignment import align
from ekfslam.analysis.parallel import run_tasks
from ekfslam.core.filter.config import CHI2_2DOF_99, FilterConfig, FilterCounts
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.geometry import wrap_angle
from ekfslam.pipeline import replay
from ekfslam.sim.scenarios import noise_for_simulation, scenario
from ekfslam.sim.simulation import simulate

#: Smallest eigenvalue of Σ allowed, as a fraction of its trace (rounding, not a real negative).
EIGENVALUE_FLOOR = -1e-9


# ------------------------------------------------------------------------------------ outliers
@dataclass(frozen=True)
class OutlierCase:
    """One row of the outlier study, summed or averaged over its runs.

    label : "clean", "wrong_id", "range" or "mixed".  wrong_id_rate, range_rate : per detection.
    gate : the NIS gate used (None: off).  map_error : mean over runs of the eq. (17) aligned
    mean landmark error, m; map_error_median likewise.  ratio : map_error / the clean run's
    (gate on).  injected : outliers the simulator put in.  accepted, rejected : update counts.
    """

    label: str
    wrong_id_rate: float
    range_rate: float
    gate: float | None
    map_error: float
    map_error_median: float
    ratio: float
    injected: int
    accepted: int
    rejected: int


@dataclass(frozen=True)
class OutlierStudy:
    """`outlier_study`'s result: the scenario, run count, rate and its rows (`OutlierCase`)."""

    scenario: str
    runs: int
    rate: float
    gate_after: int
    cases: tuple[OutlierCase, ...]

    def case(self, label: str, gated: bool = True) -> OutlierCase:
        """The row with this label, gate on (`gated`) or off."""
        return next(c for c in self.cases if c.label == label and (c.gate is not None) == gated)

    def as_dict(self) -> dict:
        return {
            "scenario": self.scenario,
            "runs": self.runs,
            "rate": self.rate,
            "gate_after": self.gate_after,
            "cases": [{f.name: getattr(c, f.name) for f in fields(c)} for c in self.cases],
        }


def outlier_study(
    name: str = "octagon",
    runs: int = 20,
    rate: float = 0.05,
    *,
    gate: float = CHI2_2DOF_99,
    gate_after: int = FilterConfig.gate_after,
    first_seed: int = 0,
    jobs: int | None = 1,
    dask: str | None = None,
) -> OutlierStudy:
    """Map error with outliers at `rate`, gate on and off, against the clean run (gate on).

    Cases: clean; wrong_id (every detection misreads its id with probability `rate`); range
    (its range is scaled by U(1.5, 3) or its inverse with probability `rate`); mixed (each at
    rate/2). Each seed gives the same underlying run in every case (the simulator draws the same
    random numbers whatever the rates), so the comparison is paired. The filter gets the
    scenario's true noise and starts at the true start. jobs, dask : where the runs go
    (`ekfslam.analysis.parallel.run_tasks`, one task per case and seed; same numbers anywhere).
    """
    kinds = {
        "clean": (0.0, 0.0),
        "wrong_id": (rate, 0.0),
        "range": (0.0, rate),
        "mixed": (rate / 2, rate / 2),
    }
    gates = (gate, None)
    tasks = [
        (name, first_seed + i, wrong, gross, gates, gate_after)
        for wrong, gross in kinds.values()
        for i in range(runs)
    ]
    done = run_tasks(_outlier_run, tasks, jobs, dask)
    cases: list[OutlierCase] = []
    for k, (label, (wrong, gross)) in enumerate(kinds.items()):
        per_seed = done[k * runs : (k + 1) * runs]
        for j, g in enumerate(gates):
            rows = [seed_rows[j] for seed_rows in per_seed]
            errors = [r[0] for r in rows]
            injected, accepted, rejected = (sum(r[m] for r in rows) for m in (1, 2, 3))
            error = float(np.mean(errors))
            clean = cases[0].map_error if cases else error  # the first case is clean, gate on
            cases.append(
                OutlierCase(
                    label,
                    wrong,
                    gross,
                    g,
                    error,
                    float(np.median(errors)),
                    error / clean,
                    injected,
                    accepted,
                    rejected,
                )
            )
    return OutlierStudy(name, runs, rate, gate_after, tuple(cases))


def _outlier_run(name, seed, wrong, gross, gates, gate_after) -> list[tuple[float, int, int, int]]:
    """One task of `outlier_study`: per gate (map error, injected, accepted, rejected)."""
    sim, arena = scenario(name, seed, outlier_wrong_id_rate=wrong, outlier_range_rate=gross)
    run, noise, tags = simulate(sim, arena), noise_for_simulation(sim), arena.tag_map()
    rows = []
    for g in gates:
        config = FilterConfig(gate=g, gate_after=gate_after)
        result = replay(run, noise, config, start=run.groundtruth.pose[0])
        rows.append(
            (
                align(result.landmarks, tags).mean_error,
                sum(run.meta.simulation["outliers"].values()),
                result.counts.accepted,
                result.counts.rejected,
            )
        )
    return rows


# ------------------------------------------------------------------------------------ long run
@dataclass(frozen=True)
class LongRun:
    """What `long_run` found.

    steps, landmarks, linearization : the run.  min_eigenvalue_ratio : the smallest
    λ_min(Σ) / trace(Σ) seen at any check, and worst_step where.  max_asymmetry : the largest
    max|Σ - Σᵀ| / max|Σ|.  finite : Σ and μ never held NaN or inf.  counts : the filter's.
    """

    steps: int
    landmarks: int
    linearization: str
    min_eigenvalue_ratio: float
    worst_step: int
    max_asymmetry: float
    finite: bool
    counts: FilterCounts
    seconds: float

    @property
    def passed(self) -> bool:
        """Finite throughout, and the smallest eigenvalue never below -1e-9 · trace."""
        return self.finite and self.min_eigenvalue_ratio >= EIGENVALUE_FLOOR


def long_run(
    steps: int = 100_000,
    linearization: str = "standard",
    seed: int = 0,
    check_every: int = 1000,
    n_landmarks: int = 12,
) -> LongRun:
    """Drive the filter `steps` steps of 0.1 s around a ring of landmarks and watch Σ.

    The true robot circles at radius 2 m and 0.3 m/s with random steering jitter; the filter is
    given the commanded increments (eq. 4), the matching R (eq. 9) and noisy range-bearing
    observations (eq. 10) of the landmarks within 3.5 m and ±60° (radius 3.5 m ring). Σ is
    checked every `check_every` steps and at the end: finite, symmetric, smallest eigenvalue
    over trace (the ratio is scale-free, so a map of any size is judged alike).
    """
    rng = np.random.default_rng(seed)
    dt, speed, radius = 0.1, 0.3, 2.0
    angles = 2.0 * np.pi * np.arange(n_landmarks) / n_landmarks
    marks = 3.5 * np.column_stack([np.cos(angles), np.sin(angles)])
    M = np.diag([0.02, 0.01, 0.03]) ** 2  # increment noise per second (m²/s, m²/s, rad²/s)
    Q = np.diag([0.03, 0.02]) ** 2
    chol_u, chol_z = np.linalg.cholesky(M * dt), np.linalg.cholesky(Q)
    truth = np.array([radius, 0.0, math.pi / 2])
    ekf = EKFSLAM(truth, config=FilterConfig(linearization=linearization), record=False)
    worst, worst_step, asym, finite = math.inf, 0, 0.0, True
    started = time.perf_counter()
    for k in range(1, steps + 1):
        # steer back onto the circle, plus jitter: valid, varied controls
        off = math.hypot(truth[0], truth[1]) - radius
        w = speed / radius + 0.5 * off + 0.1 * rng.standard_normal()
        u = np.array([speed * dt, 0.0, w * dt])
        ekf.predict_many(u[None], [dt], [k * dt], M=M)
        moved = u + chol_u @ rng.standard_normal(3)
        c, s = math.cos(truth[2]), math.sin(truth[2])
        truth = truth + np.array([c * moved[0] - s * moved[1], s * moved[0] + c * moved[1], 0.0])
        truth[2] = wrap_angle(float(truth[2] + moved[2]))
        d = marks - truth[:2]
        r = np.hypot(d[:, 0], d[:, 1])
        b = wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - truth[2])
        for i in np.flatnonzero((r < 3.5) & (np.abs(b) < math.pi / 3)):
            z = np.array([r[i], b[i]]) + chol_z @ rng.standard_normal(2)
            ekf.update(int(i), (z[0], wrap_angle(float(z[1]))), Q, k * dt)
        if k % check_every == 0 or k == steps:
            S = ekf.Sigma
            if not (np.isfinite(S).all() and np.isfinite(ekf.mu).all()):
                finite = False
                worst_step = k
                break
            asym = max(asym, float(np.abs(S - S.T).max() / np.abs(S).max()))
            ratio = float(np.linalg.eigvalsh(0.5 * (S + S.T))[0] / np.trace(S))
            if ratio < worst:
                worst, worst_step = ratio, k
    return LongRun(
        steps,
        ekf.n_landmarks,
        linearization,
        worst,
        worst_step,
        asym,
        finite,
        ekf.counts,
        time.perf_counter() - started,
    )
