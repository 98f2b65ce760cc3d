"""MRCLAM beyond loading: scoring every robot of a dataset with one noise setting.

`ekfslam.logs.mrclam.load` reads the dataset; this module asks how well the filter does on it:
`score_robots` gives the per-robot table of the README. The noise defaults in
`ekfslam.logs.mrclam.defaults.MRCLAM_NOISE` were chosen by the repository's study of a noise grid
(``python -m studies tune-mrclam``: `studies.mrclam_tuning`, `studies.mrclam_crossval`), which
scores each grid point with `score_robots`. The optional correction of the logged commands is
the dataset's knowledge, in `ekfslam.logs.mrclam.calibration`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ekfslam.analysis.evaluation import summarize
from ekfslam.analysis.rescue import replay_rescued
from ekfslam.logs.mrclam.calibration import CommandCalibration, calibrate_commands
from ekfslam.logs.mrclam.defaults import MRCLAM_CONFIG, MRCLAM_NOISE
from ekfslam.logs.mrclam.load import ROBOTS, load_mrclam
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import replay

if TYPE_CHECKING:
    from ekfslam.core.filter.config import FilterConfig
    from ekfslam.core.noise import NoiseConfig

Array = NDArray[np.float64]
# ---------------------------------------------------------------------------------------------
# Scoring robots on a whole dataset


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
    """Replay each robot with the same noise and score it (what the noise studies minimise).

    noise : None means the default: `ekfslam.logs.mrclam.defaults.MRCLAM_NOISE`, rescued where
        its replay is not ok (`ekfslam.analysis.rescue.replay_rescued`: R scaled, the most likely;
        on Datasets 1, 2, 4 and 7 as logged every robot is ok and nothing changes); config :
        None, `ekfslam.logs.mrclam.defaults.MRCLAM_CONFIG`.
    calibration : apply `calibrate_commands` first (None: the logged commands as they are).
    """
    scores = []
    for robot in robots:
        run = load_robot(str(dataset_dir), robot, calibration)
        if noise is None:  # the default: rescued where it does not fit the log (never here)
            result = replay_rescued(run, MRCLAM_NOISE, config or MRCLAM_CONFIG).result
        else:
            result = replay(run, noise, config or MRCLAM_CONFIG)
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


def _cell(metres: float) -> str:
    """A table cell in m; "none" for a robot without ground truth (no ATE, NaN in RobotScore)."""
    return "none" if math.isnan(metres) else f"{metres:.3f}"


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
            f"| {_cell(s.ate_rmse)} | {s.theta0:+.3f} | {s.seconds:.2f} |"
        )
    mean = [np.mean([getattr(s, f) for s in scores]) for f in (f.name for f in fields(RobotScore))]
    lines.append(
        f"| average | {mean[1]:.1f} | {mean[2]:.3f} | {mean[3]:.3f} | {_cell(mean[4])} "
        f"| | {mean[6]:.2f} |"  # a mean of signed rotations means nothing
    )
    return "\n".join(lines)


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
