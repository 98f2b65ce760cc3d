"""MRCLAM beyond loading: correcting its logged commands, scoring robots, tuning the noise.

`ekfslam.logs.mrclam.load` reads the dataset; this module asks how well the filter does on it. The
noise defaults in `ekfslam.pipeline.MRCLAM_NOISE` were found with `tune_noise` on Dataset 7 (see the
comment there and notebook 10); `score_robots` gives the per-robot table of the closing notes.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.logs.mrclam.load import ROBOTS, load_mrclam
from ekfslam.logs.runlog import Controls, RunLog

if TYPE_CHECKING:
    from ekfslam.core.filter.ekf import FilterConfig
    from ekfslam.pipeline import NoiseConfig

Array = NDArray[np.float64]
# ---------------------------------------------------------------------------------------------
# Command calibration: an optional, documented correction of the logged commands


@dataclass(frozen=True)
class CommandCalibration:
    """How the logged commands relate to the motion the robot made (fitted against Vicon).

    The motion over [t, t + W] is taken to be the commands over [t - lag_s, t + W - lag_s],
    scaled: forward distance by `v_scale`, turned angle by `w_scale`.
    """

    lag_s: float = 0.0
    v_scale: float = 1.0
    w_scale: float = 1.0


_LAGS = tuple(0.05 * k for k in range(9))  # 0 to 0.4 s

#: Fitted by `fit_command_calibration` on Dataset 7, pooled over robots 1-5 (1 s windows).
MRCLAM_CALIBRATION = CommandCalibration(lag_s=0.25, v_scale=0.90, w_scale=0.935)


def calibrate_commands(run: RunLog, calibration: CommandCalibration) -> RunLog:
    """The run with its controls shifted later by ``lag_s`` and (v, ω) scaled.

    Data handling, not filtering: the filter still integrates whatever twist it is given. The
    start pose stays where it was (before the shifted first command the robot stands still).
    """
    c = run.controls
    values = np.array(c.values, dtype=np.float64) * [calibration.v_scale, 1.0, calibration.w_scale]
    controls = Controls(t=c.t + calibration.lag_s, kind=c.kind, values=values)
    return dataclasses.replace(run, controls=controls)


def fit_command_calibration(
    runs: list[RunLog], lags: ArrayLike = _LAGS, window_s: float = 1.0
) -> CommandCalibration:
    """Fit one lag and two scales to several runs' commands against their ground truth.

    For every lag, the commanded forward distance and turned angle over consecutive windows of
    `window_s` are regressed (least squares through the origin, pooled over all runs) on the
    distance and the heading change that Vicon saw; the lag with the smallest residual in the
    heading wins (the heading is what the filter cannot recover afterwards).
    """
    best = None
    for lag in np.asarray(lags, dtype=float).tolist():
        pairs = [_window_motion(run, lag, window_s) for run in runs]
        cmd = np.concatenate([p[0] for p in pairs])
        true = np.concatenate([p[1] for p in pairs])
        scales = np.sum(cmd * true, axis=0) / np.sum(cmd * cmd, axis=0)
        residual = float(np.sqrt(np.mean((cmd[:, 1] * scales[1] - true[:, 1]) ** 2)))
        if best is None or residual < best[0]:
            best = (residual, CommandCalibration(lag, float(scales[0]), float(scales[1])))
    return best[1]


def _window_motion(run: RunLog, lag: float, window_s: float) -> tuple[Array, Array]:
    """(commanded, true) (|distance|, heading change) per window, each (K, 2)."""
    t, v, w = run.controls.t, run.controls.values[:, 0], run.controls.values[:, 2]
    gt = run.groundtruth
    start = max(t[0], gt.t[0]) + 1.0
    a = np.arange(start, min(t[-1], gt.t[-1]) - window_s - 1.0, window_s)
    b = a + window_s
    cum_v = np.concatenate([[0.0], np.cumsum(v[:-1] * np.diff(t))])
    cum_w = np.concatenate([[0.0], np.cumsum(w[:-1] * np.diff(t))])

    def integral(cum: Array, rate: Array, at: Array) -> Array:
        i = np.clip(np.searchsorted(t, at, side="right") - 1, 0, len(t) - 1)
        return cum[i] + rate[i] * (at - t[i])

    cmd = np.column_stack(
        [
            np.abs(integral(cum_v, v, b - lag) - integral(cum_v, v, a - lag)),
            integral(cum_w, w, b - lag) - integral(cum_w, w, a - lag),
        ]
    )
    heading = np.unwrap(gt.pose[:, 2])
    dist = np.hypot(
        np.interp(b, gt.t, gt.pose[:, 0]) - np.interp(a, gt.t, gt.pose[:, 0]),
        np.interp(b, gt.t, gt.pose[:, 1]) - np.interp(a, gt.t, gt.pose[:, 1]),
    )
    turn = np.interp(b, gt.t, heading) - np.interp(a, gt.t, heading)
    return cmd, np.column_stack([dist, turn])


# ---------------------------------------------------------------------------------------------
# Scoring robots and tuning the noise on a whole dataset


@dataclass(frozen=True)
class RobotScore:
    """One robot's replay, scored: the row of the results table.

    landmarks : how many landmarks were mapped. aligned_error : m, mean landmark error after
    the eq. (17) alignment. unaligned_error : m, the same without alignment. ate_rmse : m,
    against Vicon, no alignment. theta0 : rad, the alignment's rotation. seconds : replay time.
    """

    robot: int
    landmarks: int
    aligned_error: float
    unaligned_error: float
    ate_rmse: float
    theta0: float
    seconds: float


def score_robots(
    dataset_dir: str | Path,
    noise: NoiseConfig | None = None,
    robots: tuple[int, ...] = ROBOTS,
    calibration: CommandCalibration | None = None,
    config: FilterConfig | None = None,
) -> list[RobotScore]:
    """Replay each robot with the same noise and score it (what `tune_noise` minimises).

    noise : None means `ekfslam.pipeline.MRCLAM_NOISE`; config : None,
        `ekfslam.pipeline.MRCLAM_CONFIG`.
    calibration : apply `calibrate_commands` first (None: the logged commands as they are).
    """
    from ekfslam.analysis.evaluation import summarize
    from ekfslam.pipeline import MRCLAM_CONFIG, MRCLAM_NOISE, replay

    scores = []
    for robot in robots:
        run = load_robot(str(dataset_dir), robot, calibration)
        result = replay(run, noise or MRCLAM_NOISE, config or MRCLAM_CONFIG)
        s = summarize(run, result)
        scores.append(
            RobotScore(
                robot=robot,
                landmarks=s.landmarks_count,
                aligned_error=s.alignment.mean_error if s.alignment else math.nan,
                unaligned_error=math.nan
                if s.error_unaligned_mean is None
                else s.error_unaligned_mean,
                ate_rmse=math.nan if s.ate_rmse is None else s.ate_rmse,
                theta0=s.alignment.theta0 if s.alignment else math.nan,
                seconds=result.seconds,
            )
        )
    return scores


def scores_table(scores: list[RobotScore]) -> str:
    """The results table as Markdown, with the five-robot average as its last row."""
    lines = [
        "| robot | landmarks | mean error aligned (m) | unaligned (m) | ATE RMSE (m) "
        "| theta0 (rad) | replay (s) |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in scores:
        lines.append(
            f"| {s.robot} | {s.landmarks} | {s.aligned_error:.3f} | {s.unaligned_error:.3f} "
            f"| {s.ate_rmse:.3f} | {s.theta0:+.3f} | {s.seconds:.2f} |"
        )
    mean = [np.mean([getattr(s, f) for s in scores]) for f in RobotScore.__dataclass_fields__]
    lines.append(
        f"| average | {mean[1]:.1f} | {mean[2]:.3f} | {mean[3]:.3f} | {mean[4]:.3f} "
        f"| | {mean[6]:.2f} |"  # a mean of signed rotations means nothing
    )
    return "\n".join(lines)


#: The grid `tune_noise` searched for `ekfslam.pipeline.MRCLAM_NOISE` (sigma_y fixed at 0.005
#: m/√s: a differential drive does not slip sideways, Vicon shows < 0.01 m/s across the body).
TUNING_GRID: dict[str, tuple[float, ...]] = {
    "sigma_x": (0.005, 0.01, 0.02),
    "sigma_theta": (0.03, 0.05, 0.1),
    "sigma_range": (0.15, 0.2, 0.3),
    "sigma_bearing": (0.01, 0.02, 0.05),
}


@dataclass(frozen=True)
class TuningRow:
    """One grid point: the noise tried and the aligned landmark error of each robot (m)."""

    noise: dict[str, float]
    errors: tuple[float, ...]

    @property
    def mean(self) -> float:
        return float(np.mean(self.errors))

    @property
    def worst(self) -> float:
        return float(np.max(self.errors))


def tune_noise(
    dataset_dir: str | Path,
    grid: dict[str, tuple[float, ...]] | None = None,
    base: NoiseConfig | None = None,
    robots: tuple[int, ...] = ROBOTS,
    calibration: CommandCalibration | None = None,
    workers: int = 1,
) -> list[TuningRow]:
    """Grid search of the noise on one dataset, minimising the robots' average aligned error.

    Every combination of `grid` (field name of `ekfslam.pipeline.NoiseConfig` -> values) replays
    every robot with the same noise: one setting for all robots, never one per robot. `base`
    gives the fields the grid does not vary (default: sigma_y 0.005 m/√s, the rest NoiseConfig's).

    Returns the rows sorted best first (by the average over the robots).
    """
    import itertools
    from concurrent.futures import ProcessPoolExecutor

    from ekfslam.pipeline import NoiseConfig

    grid = TUNING_GRID if grid is None else grid
    base = base or NoiseConfig(sigma_y=0.005)
    names = list(grid)
    points = [dict(zip(names, values, strict=True)) for values in itertools.product(*grid.values())]
    jobs = [(str(dataset_dir), dataclasses.replace(base, **p), robots, calibration) for p in points]
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            errors = list(pool.map(_grid_point, jobs))
    else:
        errors = [_grid_point(job) for job in jobs]
    rows = [TuningRow(p, e) for p, e in zip(points, errors, strict=True)]
    return sorted(rows, key=lambda r: r.mean)


def _grid_point(job: tuple) -> tuple[float, ...]:
    dataset_dir, noise, robots, calibration = job
    return tuple(s.aligned_error for s in score_robots(dataset_dir, noise, robots, calibration))


_RUNS: dict[tuple, RunLog] = {}


def load_robot(
    dataset_dir: str | Path, robot: int, calibration: CommandCalibration | None = None
) -> RunLog:
    """Robot `robot` of a dataset, loaded (and calibrated) once per process: grids replay it often.

    The RunLog is shared between callers: it is frozen, never change it in place.
    """
    key = (str(Path(dataset_dir).resolve()), robot, calibration)
    if key not in _RUNS:
        run = load_mrclam(dataset_dir, robot)[0]
        _RUNS[key] = run if calibration is None else calibrate_commands(run, calibration)
    return _RUNS[key]
