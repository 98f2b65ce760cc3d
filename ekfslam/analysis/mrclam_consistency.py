"""Can we trust the ellipses on real robots? Pose NEES against MRCLAM's Vicon ground truth.

The Monte Carlo study of `ekfslam.analysis.consistency` knows the true noise; a real robot does not
tell us its noise, and there is one run per robot, not fifty. What MRCLAM does give is Vicon: the
true pose at about 60 Hz. Each robot is replayed from the Vicon pose at its first command with
zero covariance (as `ekfslam.pipeline.replay` does by default), so estimate and truth share the
Vicon frame and no alignment (eq. 17) hides an error: a map turned about the start is an error
the covariance must own.

Which rows: the filter's history has one row per event (every prediction, every update). We
keep, for each distinct history time, the LAST row, i.e. the posterior x(k|k) after the
prediction to that time and after every sighting at it; about 60 000 rows per robot, mostly
command times. Vicon is interpolated at those times (x, y linearly, the heading on its unwrapped
series, then wrapped; `ekfslam.analysis.evaluation.interpolate_poses`), and the heading error is
wrapped to [-π, π). Rows outside Vicon's span, or between two Vicon samples more than `max_gap_s`
apart (interpolating across a gap would be a guess), are left out.

One run is one draw: at each row NEES should lie in the single-run 95% chi-square(3) interval
[0.216, 9.348] 95% of the time, and its time average should be near 3. Rows of one run are
strongly correlated, so the time average is not a chi-square(3K) variable and gets no band.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ekfslam.analysis.consistency import CONFIDENCE, chi2_band, nees
from ekfslam.analysis.evaluation import interpolate_poses, summarize
from ekfslam.analysis.mrclam_tuning import load_robot
from ekfslam.analysis.parallel import run_tasks
from ekfslam.core.noise import NoiseConfig
from ekfslam.geometry import wrap_angle
from ekfslam.logs.mrclam.defaults import MRCLAM_CONFIG, MRCLAM_CONSISTENT_NOISE, MRCLAM_NOISE
from ekfslam.logs.mrclam.load import ROBOTS
from ekfslam.pipeline import replay

if TYPE_CHECKING:
    from ekfslam.core.filter.config import FilterConfig
    from ekfslam.logs.runlog import RunLog
    from ekfslam.pipeline import ReplayResult

Array = NDArray[np.float64]

LINEARIZATIONS = ("standard", "fej")
#: The single-run two-sided 95% interval of a chi-square(3) value (one run, 3 dof).
INTERVAL = tuple(float(b) for b in chi2_band(3, 1))
#: Ideal time-average of the pose NEES: the mean of chi-square(3).
IDEAL = 3.0
#: Leave out rows between Vicon samples further apart than this (Vicon runs at about 60 Hz).
MAX_GAP_S = 0.1

#: The noise settings the command line offers: tuned for the map, or for consistency.
NOISE_SETTINGS: dict[str, NoiseConfig] = {
    "map": MRCLAM_NOISE,
    "consistent": MRCLAM_CONSISTENT_NOISE,
}


@dataclass(frozen=True, eq=False)
class RobotNees:
    """One robot replayed with one linearization, its pose measured against Vicon.

    t (K,) s: the history times used (see the module docstring). error (K, 3): estimate - Vicon
    (m, m, rad, heading wrapped). nees (K,): pose NEES (3 dof). nees_heading (K,): heading NEES
    (1 dof). aligned_error : m, mean landmark error after eq. (17), as `score_robots` reports
    it. rejected : sightings the gate rejected. seconds : replay time.
    """

    robot: int
    linearization: str
    t: Array
    error: Array
    nees: Array
    nees_heading: Array
    aligned_error: float
    rejected: int
    seconds: float

    @property
    def mean(self) -> float:
        """Time average of the pose NEES (ideal 3)."""
        return float(np.mean(self.nees))

    @property
    def median(self) -> float:
        """Median pose NEES (ideal 2.37, the median of chi-square(3))."""
        return float(np.median(self.nees))

    @property
    def fraction_in_interval(self) -> float:
        """Share of the rows whose NEES lies in `INTERVAL` (ideal 0.95)."""
        return float(np.mean((self.nees >= INTERVAL[0]) & (self.nees <= INTERVAL[1])))

    def as_dict(self) -> dict:
        """The JSON row: mean, median, fraction_in_interval, heading_mean, aligned_error, ..."""
        return {
            "mean": self.mean,
            "median": self.median,
            "fraction_in_interval": self.fraction_in_interval,
            "heading_mean": float(np.mean(self.nees_heading)),
            "aligned_error": self.aligned_error,
            "rejected": self.rejected,
            "rows": len(self.t),
        }


def vicon_errors(
    run: RunLog, result: ReplayResult, max_gap_s: float = MAX_GAP_S
) -> tuple[Array, Array, Array]:
    """The filter's posterior pose error against Vicon interpolated at the filter's times.

    Parameters
    ----------
    run : a RunLog with ground truth. result : its `ekfslam.pipeline.ReplayResult`.
    max_gap_s : s, rows between Vicon samples further apart are left out.

    Returns
    -------
    t (K,) s, e (K, 3) estimate - truth (heading wrapped), P (K, 3, 3) the pose covariance
    (eqs. 9 and 16): one row per distinct history time, the last event at it.
    """
    h, gt = result.history, run.groundtruth
    if gt is None or len(gt.t) < 2:
        raise ValueError(f"run {run.meta.name!r} has no ground truth to measure errors against")
    last = np.append(h.t[1:] != h.t[:-1], True)  # the last event at each time: the posterior
    t, pose, P = h.t[last], h.pose[last], h.pose_cov[last]
    truth, inside = interpolate_poses(gt, t)
    after = np.clip(np.searchsorted(gt.t, t, side="left"), 1, len(gt.t) - 1)
    keep = inside & (gt.t[after] - gt.t[after - 1] <= max_gap_s)
    e = pose[keep] - truth[keep]
    e[:, 2] = wrap_angle(e[:, 2])
    return t[keep], e, P[keep]


def robot_nees(
    run: RunLog,
    noise: NoiseConfig = MRCLAM_NOISE,
    linearization: str = "standard",
    config: FilterConfig = MRCLAM_CONFIG,
    max_gap_s: float = MAX_GAP_S,
) -> RobotNees:
    """Replay one MRCLAM robot from its Vicon start and measure its pose NEES over time.

    config : the filter's choices; its linearization is replaced by `linearization`.
    Rows where the covariance is not positive definite (only at the very start) are left out.
    """
    started = time.perf_counter()
    result = replay(run, noise, dataclasses.replace(config, linearization=linearization))
    t, e, P = vicon_errors(run, result, max_gap_s)
    pose, heading = nees(e, P), nees(e[:, 2:], P[:, 2:, 2:])
    ok = np.isfinite(pose)
    alignment = summarize(run, result).alignment
    robot = run.meta.name.rsplit("robot", 1)[-1]
    return RobotNees(
        robot=int(robot) if robot.isdigit() else 0,
        linearization=linearization,
        t=t[ok],
        error=e[ok],
        nees=pose[ok],
        nees_heading=heading[ok],
        aligned_error=alignment.mean_error if alignment else math.nan,
        rejected=result.counts.rejected,
        seconds=time.perf_counter() - started,
    )


@dataclass(frozen=True, eq=False)
class MrclamConsistency:
    """Every robot of a dataset with every linearization, one noise setting for all.

    runs : a RobotNees per (robot, linearization), robot-major. noise_name : "map",
    "consistent" or "custom".
    """

    dataset_dir: str
    noise_name: str
    noise: NoiseConfig
    runs: tuple[RobotNees, ...]

    @property
    def robots(self) -> tuple[int, ...]:
        return tuple(dict.fromkeys(r.robot for r in self.runs))

    @property
    def linearizations(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.linearization for r in self.runs))

    @property
    def confidence(self) -> float:
        """The two-sided confidence of `interval` (`CONFIDENCE`)."""
        return CONFIDENCE

    @property
    def interval(self) -> tuple[float, float]:
        """The single-run interval of a chi-square(3) value (`INTERVAL`)."""
        return INTERVAL

    @property
    def ideal(self) -> float:
        """The mean NEES of a consistent filter (`IDEAL`: 3, the pose's dof)."""
        return IDEAL

    def get(self, robot: int, linearization: str) -> RobotNees:
        """The run of one robot with one linearization."""
        for r in self.runs:
            if r.robot == robot and r.linearization == linearization:
                return r
        raise KeyError((robot, linearization))

    def average(self, linearization: str) -> dict[str, float]:
        """The robots' average of each per-robot figure (the mean of their means, ...)."""
        rows = [self.get(robot, linearization).as_dict() for robot in self.robots]
        return {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}

    def as_dict(self) -> dict:
        """JSON-ready; the keys are listed in the ``consistency mrclam --json`` help."""
        return {
            "dataset_dir": self.dataset_dir,
            "noise_name": self.noise_name,
            "noise": dataclasses.asdict(self.noise),
            "confidence": CONFIDENCE,
            "interval": list(INTERVAL),
            "ideal": IDEAL,
            "rows_used": "posterior: last history event at each time, inside Vicon",
            "robots": {
                str(robot): {lin: self.get(robot, lin).as_dict() for lin in self.linearizations}
                for robot in self.robots
            },
            "average": {lin: self.average(lin) for lin in self.linearizations},
        }


def mrclam_consistency(
    dataset_dir: str | Path,
    noise: NoiseConfig | str = "map",
    robots: tuple[int, ...] = ROBOTS,
    linearizations: tuple[str, ...] = LINEARIZATIONS,
    config: FilterConfig = MRCLAM_CONFIG,
    jobs: int | None = 1,
    dask: str | None = None,
) -> MrclamConsistency:
    """Pose NEES against Vicon for each robot and linearization (0.2-0.6 s per replay).

    noise : a NoiseConfig, or a name in `NOISE_SETTINGS` ("map" is `MRCLAM_NOISE`).
    jobs, dask : where the robots go (`ekfslam.analysis.parallel.run_tasks`, one task each).
    Raises `ekfslam.errors.InputError` for a folder that is not a readable MRCLAM dataset.
    """
    name = noise if isinstance(noise, str) else "custom"
    if isinstance(noise, str):
        if noise not in NOISE_SETTINGS:
            raise ValueError(f"noise must be one of {sorted(NOISE_SETTINGS)}, got {noise!r}")
        noise = NOISE_SETTINGS[noise]
    tasks = [(str(dataset_dir), robot, noise, linearizations, config) for robot in robots]
    runs = tuple(r for rs in run_tasks(_robot_task, tasks, jobs, dask) for r in rs)
    return MrclamConsistency(str(dataset_dir), name, noise, runs)


def _robot_task(dataset_dir, robot, noise, linearizations, config):
    run = load_robot(dataset_dir, robot)
    return [robot_nees(run, noise, lin, config) for lin in linearizations]


def table(study: MrclamConsistency, plot: str | None = None) -> str:
    """The robot x linearization table of mean pose NEES, in-interval share and map error."""
    lins = study.linearizations
    lines = [
        f"pose NEES against Vicon, {Path(study.dataset_dir).name}, noise '{study.noise_name}' "
        f"(ideal mean {IDEAL:g}; {CONFIDENCE:.0%} interval [{INTERVAL[0]:.3f}, "
        f"{INTERVAL[1]:.3f}] for one run)",
        f"{'robot':<9}"
        + "".join(f"{lin + ' mean':>16}{'median':>8}{'in int.':>9}{'map (m)':>9}" for lin in lins),
    ]
    cells = [
        (str(robot), [study.get(robot, lin).as_dict() for lin in lins]) for robot in study.robots
    ]
    cells.append(("average", [study.average(lin) for lin in lins]))
    for label, rows in cells:
        lines.append(
            f"{label:<9}"
            + "".join(
                f"{r['mean']:>16.1f}{r['median']:>8.1f}{r['fraction_in_interval']:>9.0%}"
                f"{r['aligned_error']:>9.3f}"
                for r in rows
            )
        )
    lines.append(
        "noise: "
        + ", ".join(f"{k} {v}" for k, v in dataclasses.asdict(study.noise).items() if v is not None)
    )
    if plot:
        lines.append(f"figure written to {plot}")
    return "\n".join(lines)
