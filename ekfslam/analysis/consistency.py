"""Can we trust the ellipses? NEES and NIS over Monte Carlo runs, against chi-square bands.

A filter is *consistent* when its errors are as large as its covariance says (Bar-Shalom, Li &
Kirubarajan, 2001, sec. 5.4). With e = estimate - truth (heading wrapped) and P the filter's
covariance, the normalised estimation error squared NEES = eᵀ P⁻¹ e is chi-square with dim(e)
degrees of freedom; the normalised innovation squared NIS = νᵀ S⁻¹ ν of eqs. (13)-(15) is
chi-square with 2. N times the average of N independent runs is chi-square with N · dof, which
gives the two-sided 95% band of `chi2_band`. EKF-SLAM is known to leave that band from above: the
standard linearisation gains information about the global heading that it cannot have (Bailey et
al., IROS 2006; Huang, Mourikis & Roumeliotis, IJRR 2010); the FEJ-EKF
(`FilterConfig.linearization="fej"`) is the cheap fix, the invariant EKF (Barrau & Bonnabel 2015,
`"invariant"`) the one whose Jacobians do not depend on the estimate along the unobservable
rotation. Its covariance is that of the invariant error; `nees_pose` uses the Cartesian one
it reports, T P Tᵀ (`ekfslam.core.invariant.to_cartesian`, first order), like every other
filter's. `nees_pose_xi` scores the pose the way Barrau & Bonnabel do: the exact invariant error
ξ = log(X X̂⁻¹) (`ekfslam.core.invariant.pose_error`) against T⁻¹ Σ T⁻ᵀ, which for the invariant
filter is its own P; for the others it is their Σ seen in the same coordinates.

Monte Carlo runs are simulated with *correctly specified noise*: `noise_for_simulation` gives the
filter the simulator's own R (eq. 9) and Q (eq. 11). The filter starts at the robot's TRUE start
with zero covariance, and the scenarios set the placement error to zero too, so estimate and truth
share one frame and no alignment (eq. 17) hides anything. The scenarios are in
`ekfslam.sim.scenarios`.

The runs have no outliers by construction, so the study runs every filter without the NIS gate
(`STUDY_GATE`, None), the same choice for all three linearisations. A 99% gate there would only
censor true sightings: it drops the 1% with the largest innovations, taken when the error is
largest, and lifts the mean NEES of even an exact linear Kalman filter by about 4% of its dof
(`tests/analysis/test_gate_bias.py`; on the loop 0.09 of 3). ``gate=`` puts it back; the outlier
study (`studies.robustness.outlier_study`), whose runs do have outliers, keeps it.

The outlier study and the long run (`studies.robustness`) and the pose NEES against
MRCLAM's Vicon (`ekfslam.analysis.mrclam_consistency`) are the other subcommands of
``python -m studies consistency`` (`studies.cli.consistency`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray
from scipy.special import gammaincinv

from ekfslam.analysis.parallel import run_tasks
from ekfslam.core.filter.config import FilterConfig, FilterCounts
from ekfslam.core.filter.history import Outcome
from ekfslam.core.invariant import pose_error
from ekfslam.core.noise import NoiseConfig
from ekfslam.geometry import wrap_angle
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import ReplayResult, batch_config, replay
from ekfslam.sim.scenarios import noise_for_simulation, scenario
from ekfslam.sim.simulation import simulate

Array = NDArray[np.float64]

CONFIDENCE = 0.95

#: The NIS gate of the outlier-free consistency study: none (see the module's docstring).
STUDY_GATE: float | None = None


def chi2_band(dof: float | Array, runs: float | Array = 1, confidence: float = CONFIDENCE):
    """Two-sided band for the average of `runs` independent chi-square(dof) values.

    Returns (lower, upper) = chi2.ppf((1 ∓ confidence)/2, runs · dof) / runs; arrays broadcast.
    """
    tail = (1.0 - confidence) / 2.0
    n = np.asarray(runs, dtype=float)
    k = n * np.asarray(dof, dtype=float) / 2.0  # chi2.ppf(q, 2k) = 2 gammaincinv(k, q)
    return 2.0 * gammaincinv(k, tail) / n, 2.0 * gammaincinv(k, 1.0 - tail) / n


# ---------------------------------------------------------------------------- one run's errors
@dataclass(frozen=True, eq=False)
class RunErrors:
    """One run's normalised errors at the K ground-truth times t (K,) s.

    nees_pose (K,) 3 dof and nees_heading (K,) 1 dof of the posterior at each time (NaN while the
    covariance is singular, e.g. at the start); nees_pose_xi (K,) 3 dof, the pose NEES in the
    invariant error's coordinates (`pose_nees_xi`). landmark_sum/landmark_count (K,): NEES (2 dof)
    of every landmark sighted at that time, its estimate right after the sighting. nis_sum /
    nis_count (K,): NIS of every innovation the filter computed there, accepted or gated.
    map_nees : the whole final map's NEES, map_dof = 2n its dof.
    """

    t: Array
    nees_pose: Array
    nees_heading: Array
    nees_pose_xi: Array
    landmark_sum: Array
    landmark_count: Array
    nis_sum: Array
    nis_count: Array
    map_nees: float
    map_dof: int


def nees(e: Array, P: Array) -> Array:
    """NEES eᵀ P⁻¹ e for stacks e (K, d), P (K, d, d); NaN where P is not positive definite."""
    out = np.full(len(e), np.nan)
    ok = np.isfinite(e).all(axis=1)
    ok[ok] = np.linalg.eigvalsh(P[ok])[:, 0] > 1e-15
    if ok.any():
        out[ok] = np.einsum("ki,ki->k", e[ok], np.linalg.solve(P[ok], e[ok][..., None])[..., 0])
    return out


def pose_errors(run: RunLog, result: ReplayResult) -> tuple[Array, Array, Array]:
    """The posterior pose error and covariance at each ground-truth time.

    Returns t (K,) s, e (K, 3) = estimate - truth (heading wrapped; NaN before the first
    event) and P (K, 3, 3), the filter's pose covariance then (eqs. 9 and 16).
    """
    h, gt = result.history, run.groundtruth
    if gt is None:
        raise ValueError(f"run {run.meta.name!r} has no ground truth to measure errors against")
    idx = np.searchsorted(h.t, gt.t, side="right") - 1  # the last event at or before each time
    e = h.pose[np.maximum(idx, 0)] - gt.pose
    e[:, 2] = wrap_angle(e[:, 2])
    e[idx < 0] = np.nan
    return np.asarray(gt.t, dtype=float), e, h.pose_cov[np.maximum(idx, 0)]


def pose_nees_xi(truth: Array, estimate: Array, P: Array) -> Array:
    """Pose NEES (K,) in the invariant error's coordinates, the way Barrau & Bonnabel score it.

    truth, estimate (K, 3) poses; P (K, 3, 3) the Cartesian pose covariance. The error is the
    exact ξ = log(X X̂⁻¹) (`ekfslam.core.invariant.pose_error`) and its covariance
    T⁻¹ P T⁻ᵀ, T⁻¹ = I - (-ŷ, x̂, 0) e₃ᵀ: the exact inverse of the map the invariant filter
    reports P with, so for that filter this is its own covariance.
    """
    Tinv = np.broadcast_to(np.eye(3), (len(P), 3, 3)).copy()
    Tinv[:, 0, 2], Tinv[:, 1, 2] = estimate[:, 1], -estimate[:, 0]
    P_xi = Tinv @ P @ Tinv.transpose(0, 2, 1)
    return nees(pose_error(truth, estimate), P_xi)


def run_errors(run: RunLog, result: ReplayResult) -> RunErrors:
    """Score a replay of a simulated run against its ground truth (see `RunErrors`)."""
    t, e, P = pose_errors(run, result)
    h, gt, tags = result.history, run.groundtruth, run.meta.tag_map or {}
    k = len(t)
    nees_pose, nees_heading = nees(e, P), nees(e[:, 2:], P[:, 2:, 2:])
    estimate = gt.pose + e  # NaN before the first event, and then so is the NEES
    nees_xi = pose_nees_xi(gt.pose, estimate, P)
    step = np.minimum(np.searchsorted(gt.t, h.obs_t, side="left"), k - 1)
    seen = np.isfinite(h.obs_landmark[:, 0]) & np.isin(h.obs_id, list(tags))
    truth = np.array([tags[i] for i in h.obs_id[seen].tolist()]).reshape(-1, 2)
    lm = nees(h.obs_landmark[seen] - truth, h.obs_landmark_cov[seen])
    computed = h.outcome_mask(Outcome.ACCEPTED, Outcome.REJECTED)
    ids = list(result.landmarks)  # slot order: slot j is state rows 3 + 2j, 4 + 2j
    js = [j for j, i in enumerate(ids) if i in tags]
    rows = np.array([[3 + 2 * j, 4 + 2 * j] for j in js], dtype=np.int64).ravel()
    err = np.array([result.landmarks[ids[j]] - tags[ids[j]] for j in js]).ravel()
    S = result.Sigma[np.ix_(rows, rows)]
    return RunErrors(
        t=t,
        nees_pose=nees_pose,
        nees_heading=nees_heading,
        nees_pose_xi=nees_xi,
        landmark_sum=np.bincount(step[seen][np.isfinite(lm)], lm[np.isfinite(lm)], k),
        landmark_count=np.bincount(step[seen][np.isfinite(lm)], minlength=k).astype(float),
        nis_sum=np.bincount(step[computed], h.obs_nis[computed], k),
        nis_count=np.bincount(step[computed], minlength=k).astype(float),
        map_nees=float(err @ np.linalg.solve(S, err)) if js else math.nan,
        map_dof=2 * len(js),
    )


# ------------------------------------------------------------------------------ Monte Carlo
@dataclass(frozen=True, eq=False)
class Consistency:
    """The average of `runs` runs at each of K steps, with its 95% bands.

    t (K,) s. nees_pose (K,), nees_heading (K,): averages over runs; band_pose, band_heading
    (2,) their bands. nees_pose_xi (K,): the pose NEES in the invariant error's coordinates
    (`pose_nees_xi`), averaged, in band_pose too. nees_landmark (K,): per run the mean NEES
    of the landmarks sighted at that step, averaged over the runs that sighted one;
    band_landmark (2, K) for that many runs of 2 dof (conservative: it treats one run's
    sightings as one draw). nis (K,): the mean NIS of every innovation computed at that step in
    any run; band_nis (2, K) for that many 2-dof draws (sequential innovations are
    uncorrelated). map_nees (runs,): final map NEES, 2n dof.
    counts : the filters' counts summed over the runs.
    """

    scenario: str
    linearization: str
    runs: int
    t: Array
    nees_pose: Array
    nees_heading: Array
    nees_pose_xi: Array
    nees_landmark: Array
    nis: Array
    band_pose: Array
    band_heading: Array
    band_landmark: Array
    band_nis: Array
    map_nees: Array
    map_dof: int
    counts: FilterCounts
    noise: NoiseConfig
    gate: float | None
    seconds: float
    iterations: int = 1  # `FilterConfig.iterations`: linearisations per update

    @property
    def confidence(self) -> float:
        """The two-sided confidence of the bands (`CONFIDENCE`), for a figure to say."""
        return CONFIDENCE

    @property
    def band_pose_xi(self) -> Array:
        """The band of `nees_pose_xi`: the pose's, 3 dof."""
        return self.band_pose

    def fraction_in_band(self, name: str) -> float:
        """Share of the steps with a value (not NaN) whose average lies inside its band."""
        value = getattr(self, name)
        lo, hi = getattr(self, "band_" + name.removeprefix("nees_"))
        ok = np.isfinite(value)
        inside = (value >= lo) & (value <= hi)
        return float(inside[ok].mean()) if ok.any() else math.nan

    def as_dict(self) -> dict:
        """JSON-ready summary: per quantity its time-average, fraction in band, max and band."""

        def stats(name: str) -> dict:
            v = getattr(self, name)
            band = getattr(self, "band_" + name.removeprefix("nees_"))
            lo, hi = band if band.ndim == 1 else band[:, np.isfinite(v)]
            return {
                "mean": float(np.nanmean(v)),
                "fraction_in_band": self.fraction_in_band(name),
                "max": float(np.nanmax(v)),
                "band": [float(np.nanmedian(lo)), float(np.nanmedian(hi))],
            }

        map_band = chi2_band(self.map_dof, self.runs)
        return {
            "scenario": self.scenario,
            "linearization": self.linearization,
            "runs": self.runs,
            "steps": len(self.t),
            "confidence": CONFIDENCE,
            "band": [float(b) for b in self.band_pose],
            "nees_pose": stats("nees_pose"),
            "nees_heading": stats("nees_heading"),
            "nees_pose_xi": stats("nees_pose_xi"),
            "nees_landmark": stats("nees_landmark"),
            "nis": stats("nis") | {"innovations": self.counts.accepted + self.counts.rejected},
            "map_nees_final": {
                "mean": float(np.mean(self.map_nees)),
                "dof": self.map_dof,
                "band": [float(b) for b in map_band],
            },
            "updates": dataclasses.asdict(self.counts),
            "gate": self.gate,
            "iterations": self.iterations,
            "noise": dataclasses.asdict(self.noise),
            "seconds": self.seconds,
        }


def monte_carlo(
    name: str = "octagon",
    runs: int = 50,
    linearization: str = "standard",
    *,
    gate: float | None = STUDY_GATE,
    first_seed: int = 0,
    wheel_noise_sigma: float | None = None,
    iterations: int = 1,
    jobs: int | None = 1,
    dask: str | None = None,
) -> Consistency:
    """Simulate `runs` runs of a scenario (seeds first_seed, first_seed + 1, ...) and average.

    Each run is replayed with `noise_for_simulation` and FilterConfig(linearization, gate),
    starting at the true start with zero covariance; gate is `STUDY_GATE` (none: the runs have
    no outliers) unless given. See `Consistency` for what comes back.
    """
    return compare(
        name,
        runs,
        (linearization,),
        gate=gate,
        first_seed=first_seed,
        wheel_noise_sigma=wheel_noise_sigma,
        iterations=iterations,
        jobs=jobs,
        dask=dask,
    )[0]


def compare(
    name: str = "octagon",
    runs: int = 50,
    linearizations: tuple[str, ...] = ("standard", "fej"),
    *,
    gate: float | None = STUDY_GATE,
    first_seed: int = 0,
    wheel_noise_sigma: float | None = None,
    iterations: int = 1,
    jobs: int | None = 1,
    dask: str | None = None,
) -> tuple[Consistency, ...]:
    """`monte_carlo` for several linearizations on the very same simulated runs.

    iterations : `FilterConfig.iterations` (the iterated update) for the filters that take it;
    FEJ always runs with one.

    jobs, dask : where the runs go (`ekfslam.analysis.parallel.run_tasks`): one task per seed,
    the same numbers whatever the backend (only `seconds` differs).
    """
    if runs < 1:
        raise ValueError(f"runs must be at least 1, got {runs}")
    configs = [
        FilterConfig(linearization=lin, gate=gate, iterations=1 if lin == "fej" else iterations)
        for lin in linearizations
    ]
    replays = runs * len(configs)  # of the same length: together they decide the backend
    tasks = [(name, first_seed + i, wheel_noise_sigma, configs, replays) for i in range(runs)]
    done = run_tasks(_one_run, tasks, jobs, dask)
    noise = done[-1][1]
    out = []
    for c, config in enumerate(configs):
        counts = dict.fromkeys((f.name for f in fields(FilterCounts)), 0)
        for per_config, _ in done:
            for key in counts:
                counts[key] += getattr(per_config[c][1], key)
        errors = [per_config[c][0] for per_config, _ in done]
        seconds = sum(per_config[c][2] for per_config, _ in done)
        out.append(_average(name, errors, config, counts, noise, seconds))
    return tuple(out)


def _one_run(
    name: str,
    seed: int,
    wheel_noise_sigma: float | None,
    configs: list[FilterConfig],
    replays: int,
):
    """One Monte Carlo task: simulate seed, replay it with each config (one of `replays` like it).

    Returns ([(RunErrors, FilterCounts, seconds) per config], the noise the filter got).
    """
    sim, arena = scenario(name, seed, wheel_noise_sigma)
    run, noise = simulate(sim, arena), noise_for_simulation(sim)
    per_config = []
    for config in configs:
        started = time.perf_counter()
        batch = batch_config(run, replays, config)  # one of `replays` like it
        result = replay(run, noise, batch, start=run.groundtruth.pose[0])
        errors = run_errors(run, result)
        per_config.append((errors, result.counts, time.perf_counter() - started))
    return per_config, noise


def _average(name, errors, config, counts, noise, seconds) -> Consistency:
    runs = len(errors)
    if len({len(e.t) for e in errors}) != 1:
        raise RuntimeError("runs of one scenario must share their time steps")
    stack = {
        f: np.array([getattr(e, f) for e in errors]) for f in (f.name for f in fields(RunErrors))
    }
    with np.errstate(invalid="ignore", divide="ignore"):
        lm_runs = stack["landmark_sum"] / stack["landmark_count"]  # NaN where none was sighted
        lm_n = np.isfinite(lm_runs).sum(axis=0)
        nis_n = stack["nis_count"].sum(axis=0)
        nis = stack["nis_sum"].sum(axis=0) / nis_n
        nees_landmark = np.nansum(lm_runs, axis=0) / lm_n

    def mean_over_runs(a: Array) -> Array:
        # a step counts only once every run has a covariance there (none has at the start)
        return np.where(np.isfinite(a).all(axis=0), a.mean(axis=0), np.nan)

    return Consistency(
        scenario=name,
        linearization=config.linearization,
        runs=runs,
        t=errors[0].t,
        nees_pose=mean_over_runs(stack["nees_pose"]),
        nees_heading=mean_over_runs(stack["nees_heading"]),
        nees_pose_xi=mean_over_runs(stack["nees_pose_xi"]),
        nees_landmark=nees_landmark,
        nis=nis,
        band_pose=np.array(chi2_band(3, runs)),
        band_heading=np.array(chi2_band(1, runs)),
        band_landmark=np.array(chi2_band(2, np.maximum(lm_n, 1))),
        band_nis=np.array(chi2_band(2, np.maximum(nis_n, 1))),
        map_nees=stack["map_nees"],
        map_dof=int(errors[0].map_dof),
        counts=FilterCounts(**counts),
        noise=noise,
        gate=config.gate,
        seconds=seconds,
        iterations=config.iterations,
    )
