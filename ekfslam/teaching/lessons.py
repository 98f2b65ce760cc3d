"""Plumbing for the classroom notebooks: cutting a run, one update taken apart, per-lap numbers.

The notebooks show the seed's equations and a few lines of code; what they need besides the
filter lives here, so that nothing in a notebook is a copy of the package:

- pieces of a run: `without_detections` (dead reckoning), `truncate` and `replay_until`
  (the filter's state, full covariance included, at any time of a run);
- the frame the filter works in: it starts at the nominal pose, the robot did not
  (`filter_frame_transform`, `truth_in_filter_frame`, `tags_in_filter_frame`, `position_errors`);
- one correction written literally with F_x,j, eqs. (13)-(16), in the seed's form and Joseph's
  (`update_steps`);
- the seed's "driving multiple times" and "trade-off of the trajectory" as numbers
  (`lap_statistics`, `revisits`, `size_sweep`), Table 1 beside the seed's (`table1_markdown`);
- `check_answer` for the exercises; `mrclam_dataset`, which stops a notebook in one line when
  the data is not there (`NotebookStop`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.analysis.alignment import align
from ekfslam.analysis.evaluation import RunSummary, interpolate_poses
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.history import History
from ekfslam.core.models import observation, observation_jacobians
from ekfslam.core.noise import NoiseConfig
from ekfslam.errors import AlignmentError, EkfSlamError, InputError
from ekfslam.geometry import compose, invert, transform_points, wrap_angle
from ekfslam.logs.mrclam.load import find_dataset
from ekfslam.logs.runlog import Controls, Detections, GroundTruth, RunLog
from ekfslam.pipeline import ReplayResult, replay
from ekfslam.sim.simulation import SimulationConfig, simulate
from ekfslam.teaching.derivations import landmark_lift_matrix_numeric

Array = NDArray[np.float64]

# --- pieces of a run ----------------------------------------------------------------------------


def without_detections(run: RunLog) -> RunLog:
    """The same run with every detection removed: replaying it is dead reckoning (eqs. 6, 9)."""
    empty = Detections(
        t=np.zeros(0), tag_id=np.zeros(0, dtype=np.int64), range=np.zeros(0), bearing=np.zeros(0)
    )
    return replace(run, detections=empty)


def truncate(run: RunLog, t_end: float, max_detections: int | None = None) -> RunLog:
    """The run up to time `t_end` (s): controls, detections and ground truth with t <= t_end.

    With `max_detections`, only the first that many detections are kept (as well).

    The control row in force at `t_end` is repeated at `t_end`, so a replay integrates the motion
    right up to that time (a log's last row is otherwise never held beyond its own time).
    """
    c = run.controls
    keep = np.asarray(c.t) <= t_end
    if not keep.any():
        raise ValueError(f"t_end = {t_end} s is before the first control ({c.t[0]} s)")
    t = np.append(np.asarray(c.t)[keep], t_end)
    values = np.vstack([np.asarray(c.values)[keep], np.asarray(c.values)[keep][-1:]])
    d = run.detections
    seen = np.asarray(d.t) <= t_end
    if max_detections is not None:
        seen &= np.arange(len(seen)) < max_detections
    detections = Detections(
        t=d.t[seen], tag_id=d.tag_id[seen], range=d.range[seen], bearing=d.bearing[seen]
    )
    truth = run.groundtruth
    if truth is not None:
        inside = np.asarray(truth.t) <= t_end
        truth = GroundTruth(t=truth.t[inside], pose=truth.pose[inside])
    return replace(
        run,
        controls=Controls(t=t, kind=c.kind, values=values),
        detections=detections,
        groundtruth=truth,
    )


def replay_until(
    run: RunLog,
    t_end: float,
    noise: NoiseConfig | None = None,
    config: FilterConfig | None = None,
) -> ReplayResult:
    """Replay the run up to `t_end` (s): the filter's state, with its full Σ, at that time.

    Cut at a detection time, the result is exactly the full replay's state after that detection
    (the prediction pieces are the same); cut between detections, the last piece is split.
    """
    return replay(truncate(run, t_end), noise, config)


def prior_before(
    run: RunLog, k: int, noise: NoiseConfig | None = None, config: FilterConfig | None = None
) -> ReplayResult:
    """The state just before detection k is used: predicted to its time, detections 0..k-1 applied.

    Feeding detection k to `update_steps` with this state is the step the full replay takes.
    """
    return replay(truncate(run, float(run.detections.t[k]), max_detections=k), noise, config)


def landmark_slots(result: ReplayResult) -> list[int]:
    """Landmark ids in the order of their slots in `result.mu` (slot j at indices 3+2j, 4+2j)."""
    ids = list(result.landmarks)
    for j, i in enumerate(ids):
        if not np.array_equal(result.mu[3 + 2 * j : 5 + 2 * j], result.landmarks[i]):
            raise EkfSlamError(f"landmark {i} is not in slot {j} of the state")
    return ids


# --- the filter's frame -------------------------------------------------------------------------


def filter_frame_transform(run: RunLog) -> Array:
    """T (3,) with filter pose = T ⊕ world pose.

    The filter starts at the nominal start while the robot stood at the true one (the ground
    truth's first pose), so the filter's map is the world seen from a frame in which the true start
    sits at the nominal one: T = nominal ⊕ ⊖true_start. Needs ground truth.
    """
    if run.groundtruth is None or not len(run.groundtruth.t):
        raise EkfSlamError(f"run {run.meta.name!r} has no ground truth")
    return compose(run.meta.nominal_start, invert(run.groundtruth.pose[0]))


def truth_in_filter_frame(run: RunLog) -> GroundTruth:
    """The ground truth poses expressed in the filter's frame (see `filter_frame_transform`)."""
    T = filter_frame_transform(run)
    poses = np.array([compose(T, p) for p in run.groundtruth.pose]).reshape(-1, 3)
    return GroundTruth(t=np.asarray(run.groundtruth.t, dtype=float), pose=poses)


def tags_in_filter_frame(run: RunLog) -> dict[int, Array]:
    """{tag id: (2,) m}: where a perfect filter would put each tag (needs ground truth, tags)."""
    if not run.meta.tag_map:
        raise EkfSlamError(f"run {run.meta.name!r} has no tag map")
    T = filter_frame_transform(run)
    return {i: transform_points(T, p)[0] for i, p in run.meta.tag_map.items()}


def position_errors(run: RunLog, history: History) -> tuple[Array, Array]:
    """Times (K,) s and position errors (K,) m of a history's poses against the truth.

    Both in the filter's frame, so no fitting is involved; events outside the ground truth's span
    are dropped.
    """
    truth, inside = interpolate_poses(truth_in_filter_frame(run), history.t)
    err = np.hypot(*(history.pose[inside, :2] - truth[inside, :2]).T)
    return history.t[inside], err


# --- one correction, literally ------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class UpdateSteps:
    """Every intermediate of one correction, eqs. (13)-(16), for a state of size d = 3 + 2n.

    z_hat (2,) eq. (13); nu (2,) innovation z - ẑ, bearing wrapped; H (2, d) eq. (14) with
    F_x,j; S (2, 2) innovation covariance H Σ Hᵀ + Q; K (d, 2) eq. (15); nis νᵀ S⁻¹ ν;
    mu_prior / mu_post (d,) eq. (16); Sigma_prior, Sigma_seed = (I - KH) Σ as printed in
    eq. (16), Sigma_joseph = (I - KH) Σ (I - KH)ᵀ + K Q Kᵀ, all (d, d).
    """

    j: int
    z: Array
    z_hat: Array
    nu: Array
    H: Array
    S: Array
    K: Array
    nis: float
    mu_prior: Array
    mu_post: Array
    Sigma_prior: Array
    Sigma_seed: Array
    Sigma_joseph: Array


def update_steps(
    mu: ArrayLike, Sigma: ArrayLike, j: int, z: ArrayLike, Q: ArrayLike
) -> UpdateSteps:
    """One EKF correction with landmark slot j, written as the seed writes it (eqs. 13-16).

    Parameters
    ----------
    mu : (d,) prior mean, eq. (1); Sigma : (d, d) its covariance.
    j : the landmark's slot (0-based; indices 3+2j, 4+2j).
    z : (2,) measured range (m) and bearing (rad), eq. (10); Q : (2, 2) eq. (11).
    """
    mu = np.array(mu, dtype=float)
    Sigma = np.array(Sigma, dtype=float)
    z = np.asarray(z, dtype=float)
    Q = np.asarray(Q, dtype=float)
    n = (len(mu) - 3) // 2
    pose, landmark = mu[:3], mu[3 + 2 * j : 5 + 2 * j]
    z_hat = observation(pose, landmark)  # eq. (13), with atan2
    H_pose, H_landmark = observation_jacobians(pose, landmark)
    H = np.hstack([H_pose, H_landmark]) @ landmark_lift_matrix_numeric(n, j)  # eq. (14)
    S = H @ Sigma @ H.T + Q
    K = Sigma @ H.T @ np.linalg.inv(S)  # eq. (15)
    nu = z - z_hat
    nu[1] = wrap_angle(float(nu[1]))
    mu_post = mu + K @ nu  # eq. (16)
    mu_post[2] = wrap_angle(float(mu_post[2]))
    I_KH = np.eye(len(mu)) - K @ H
    return UpdateSteps(
        j=j,
        z=z.copy(),
        z_hat=z_hat,
        nu=nu,
        H=H,
        S=S,
        K=K,
        nis=float(nu @ np.linalg.solve(S, nu)),
        mu_prior=mu,
        mu_post=mu_post,
        Sigma_prior=Sigma,
        Sigma_seed=I_KH @ Sigma,
        Sigma_joseph=I_KH @ Sigma @ I_KH.T + K @ Q @ K.T,
    )


# --- laps: the seed's "driving multiple times" --------------------------------------------------


def lap_times(run: RunLog) -> Array:
    """End time (s) of each lap of a simulated run, from its waypoint times; shape (laps,)."""
    sim = run.meta.simulation
    if not sim or "waypoint_times" not in sim:
        raise EkfSlamError(f"run {run.meta.name!r} is not a simulated run with waypoint times")
    per_lap = 4 if sim["trajectory"] == "square" else 8
    times = np.asarray(sim["waypoint_times"], dtype=float)
    return times[per_lap::per_lap][: int(sim["laps"])]


@dataclass(frozen=True)
class LapStats:
    """Error and uncertainty over one lap (m).

    position_rmse : RMS position error over the lap's events, in the filter's frame.
    position_sd : mean over the lap of √(σ_xx + σ_yy), the robot's position uncertainty.
    map_error : eq. (17) mean distance after aligning the map at the lap's end (NaN below 2).
    map_error_unaligned : mean distance to the tags in the filter's frame at the lap's end.
    map_sd : mean over landmarks of √(trace Σ_ll) at the lap's end.
    """

    lap: int
    t_start: float
    t_end: float
    landmarks: int
    position_rmse: float
    position_sd: float
    map_error: float
    map_error_unaligned: float
    map_sd: float


def lap_statistics(
    run: RunLog, noise: NoiseConfig | None = None, config: FilterConfig | None = None
) -> tuple[LapStats, ...]:
    """Replay a simulated run and score each lap: the trajectory over it, the map at its end."""
    ends = lap_times(run)
    full = replay(run, noise, config)
    h = full.history
    t_err, err = position_errors(run, h)
    sd = np.sqrt(h.pose_cov[:, 0, 0] + h.pose_cov[:, 1, 1])
    tags = tags_in_filter_frame(run)
    out = []
    for k, t1 in enumerate(ends):
        t0 = 0.0 if k == 0 else float(ends[k - 1])
        lap_err = err[(t_err > t0) & (t_err <= t1)]
        lap_sd = sd[(h.t > t0) & (h.t <= t1)]
        at_end = replay_until(run, float(t1), noise, config)
        lm = at_end.landmarks
        try:
            map_error = align(lm, run.meta.tag_map).mean_error
        except AlignmentError:
            map_error = math.nan
        unaligned = [np.hypot(*(lm[i] - tags[i])) for i in lm if i in tags]
        spread = [math.sqrt(np.trace(c)) for c in at_end.landmark_covariances.values()]
        out.append(
            LapStats(
                lap=k + 1,
                t_start=t0,
                t_end=float(t1),
                landmarks=len(lm),
                position_rmse=float(np.sqrt(np.mean(lap_err**2))) if len(lap_err) else math.nan,
                position_sd=float(lap_sd.mean()) if len(lap_sd) else math.nan,
                map_error=float(map_error),
                map_error_unaligned=float(np.mean(unaligned)) if unaligned else math.nan,
                map_sd=float(np.mean(spread)) if spread else math.nan,
            )
        )
    return tuple(out)


def revisits(history: History, gap: float = 10.0) -> tuple[Array, NDArray[np.int64]]:
    """Times (s) and ids of accepted sightings of a tag last seen more than `gap` s before.

    These are the seed's "sees landmarks it has seen before": the moments the uncertainty drops.
    """
    accepted = history.outcome_mask("accepted") | history.outcome_mask("initialised")
    last: dict[int, float] = {}
    times, ids = [], []
    for t, i, ok in zip(history.obs_t.tolist(), history.obs_id.tolist(), accepted, strict=True):
        if not ok:
            continue
        if i in last and t - last[i] > gap:
            times.append(t)
            ids.append(i)
        last[i] = t
    return np.array(times, dtype=float), np.array(ids, dtype=np.int64)


# --- the seed's "trade-off of the trajectory" ---------------------------------------------------


@dataclass(frozen=True)
class SweepPoint:
    """One simulated run of the size sweep: path, size (m), seed, and its scores (m)."""

    trajectory: str
    size: float
    seed: int
    landmarks: int
    map_error: float  # eq. (17), mean distance after alignment; NaN with fewer than 2 landmarks
    position_rmse: float  # trajectory error in the filter's frame


def size_sweep(
    trajectories: Iterable[str] = ("square", "octagon"),
    sizes: Iterable[float] = (0.4, 0.7, 1.0),
    seeds: Iterable[int] = (1, 2),
    noise: NoiseConfig | None = None,
    laps: int = 2,
) -> tuple[SweepPoint, ...]:
    """Simulate and replay every (trajectory, size, seed) with the default simulator settings."""
    out = []
    for trajectory in trajectories:
        for size in sizes:
            for seed in seeds:
                cfg = SimulationConfig(trajectory=trajectory, size=size, seed=seed, laps=laps)
                run = simulate(cfg)
                result = replay(run, noise)
                try:
                    error = align(result.landmarks, run.meta.tag_map).mean_error
                except AlignmentError:
                    error = math.nan
                _, err = position_errors(run, result.history)
                rmse = float(np.sqrt(np.mean(err**2)))
                point = SweepPoint(
                    trajectory, float(size), seed, len(result.landmarks), error, rmse
                )
                out.append(point)
    return tuple(out)


# --- tables and exercises -----------------------------------------------------------------------


def table1_markdown(
    summaries: Mapping[str, RunSummary], seed_table: Mapping[str, Sequence[float]]
) -> str:
    """The seed's Table 1 as a Markdown table: each of our runs beside the seed's row.

    summaries : {trajectory name ("square", ...): RunSummary with an alignment}.
    seed_table : {trajectory name: (x0, y0, θ0, average error)},
        e.g. `ekfslam.analysis.evaluation.SEED_TABLE1`.
    """
    lines = [
        "| Trajectory | x0 (m) | y0 (m) | θ0 (rad) | Average error (m) |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, summary in summaries.items():
        a = summary.alignment
        if a is None:
            raise EkfSlamError(f"run {name!r} has no alignment (no tag map?)")
        lines.append(
            f"| {name}, this simulation | {a.x0:.3f} | {a.y0:.3f} | {a.theta0:.3f} "
            f"| {a.mean_error:.3f} |"
        )
        if name in seed_table:
            x0, y0, t0, err = seed_table[name]
            lines.append(f"| {name}, seed report (real robot) | {x0:.3f} | {y0:.3f} | {t0:.3f} "
                         f"| {err:.3f} |")  # fmt: skip
    return "\n".join(lines)


def check_answer(answer: object, expected: ArrayLike, atol: float = 1e-6) -> bool:
    """Compare an exercise's answer with the expected value and print a verdict.

    Returns True when `answer` has the expected shape and agrees within `atol`; None (not
    answered yet) and anything of the wrong shape print a hint instead of raising.
    """
    if answer is None:
        print("Not answered yet: replace None with your answer and run this cell again.")
        return False
    try:
        got = np.asarray(answer, dtype=float)
        want = np.asarray(expected, dtype=float)
        if got.shape != want.shape:
            print(f"Not yet: the answer has shape {got.shape}, the expected one {want.shape}.")
            return False
        ok = bool(np.allclose(got, want, rtol=0.0, atol=atol))
    except (TypeError, ValueError):
        print(f"Not yet: {answer!r} is not a number or an array of numbers.")
        return False
    print("Right!" if ok else f"Not yet: off by up to {np.max(np.abs(got - want)):.3g}.")
    return ok


class NotebookStop(EkfSlamError):
    """Stops a notebook at this cell. Jupyter shows the message as one line, with no traceback,
    and *Run All* runs no further cell (they need what this one could not give)."""

    def _render_traceback_(self) -> list[str]:  # IPython shows these lines, not a traceback
        return [str(self)]


def mrclam_dataset(n: int = 7) -> Path:
    """The folder of MRCLAM dataset n (`ekfslam.logs.mrclam.load.find_dataset`) for a notebook.

    Raises
    ------
    NotebookStop
        It is not on this machine; the one line says how to fetch it.
    """
    try:
        return find_dataset(n)
    except InputError:
        raise NotebookStop(
            f"MRCLAM Dataset {n} is not on this machine, and the rest of this notebook needs it. "
            f"Fetch it with `python -m ekfslam fetch mrclam {n}` (from its publisher) "
            "and run the notebook again."
        ) from None
