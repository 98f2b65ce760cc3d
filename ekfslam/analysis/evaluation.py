"""Scores of a replay: the seed's Table 1 row (eq. 17 alignment) and trajectory error.

`summarize` gathers everything the command line prints into one frozen `RunSummary`; its
`as_dict` gives the nested JSON that ``python -m ekfslam run --json`` prints.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ekfslam import checks
from ekfslam.analysis.alignment import METHODS, Alignment, align
from ekfslam.core.filter.history import Outcome
from ekfslam.errors import AlignmentError
from ekfslam.geometry import wrap_angle
from ekfslam.logs.runlog import GroundTruth, RunLog
from ekfslam.pipeline import ReplayResult, replay

# the command line (cli.main) asks here whether a run is one of the seed's experiments
from ekfslam.sim.config import seed_experiment  # noqa: F401

if TYPE_CHECKING:
    from ekfslam.core.diagnosis import Diagnosis
    from ekfslam.core.filter.config import FilterConfig
    from ekfslam.core.noise import NoiseConfig

Array = NDArray[np.float64]

#: The seed's Table 1, from the real robot: (x0, y0, θ0, average error) in m, m, rad, m.
SEED_TABLE1 = {"square": (-0.020, 0.056, 0.142, 0.153), "octagon": (-0.040, 0.043, 0.137, 0.130)}
#: The order of the outcome counts under "updates" in `RunSummary.as_dict` (the JSON keeps it).
UPDATES_ORDER = (
    Outcome.ACCEPTED,
    Outcome.REJECTED,
    Outcome.REFUSED,
    Outcome.INITIALISED,
    Outcome.REINITIALISED,
    Outcome.SINGULAR,
    Outcome.DEFERRED,
)


def interpolate_poses(groundtruth: GroundTruth, t: Array) -> tuple[Array, NDArray[np.bool_]]:
    """True poses at times t (linear in x, y and in the unwrapped heading).

    Returns the poses (len(t), 3) and a mask of the times inside the ground truth's span (poses
    outside it are NaN: ground truth that ends early is not extrapolated).
    """
    gt_t = np.asarray(groundtruth.t, dtype=float)
    pose = np.asarray(groundtruth.pose, dtype=float)
    inside = (t >= gt_t[0]) & (t <= gt_t[-1])
    out = np.full((len(t), 3), np.nan)
    theta = np.unwrap(pose[:, 2])
    for c, column in enumerate((pose[:, 0], pose[:, 1], theta)):
        out[inside, c] = np.interp(t[inside], gt_t, column)
    out[inside, 2] = wrap_angle(out[inside, 2])
    return out, inside


def ate_rmse(result: ReplayResult, groundtruth: GroundTruth) -> float:
    """Absolute trajectory error: RMS position error of the estimate against ground truth.

    Evaluated at every event time of the history that falls inside the ground truth's span, with
    no alignment (the estimate and the truth must share a frame).
    """
    checks.instance(
        result, ReplayResult, "ate_rmse: result", "replay a run first: ekfslam.replay(run)"
    )
    checks.instance(
        groundtruth,
        GroundTruth,
        "ate_rmse: groundtruth",
        "pass the run's ground truth, run.groundtruth (a run without one has no trajectory error)",
    )
    h = result.history
    truth, inside = interpolate_poses(groundtruth, h.t)
    if not inside.any():
        return float("nan")
    err = h.pose[inside, :2] - truth[inside, :2]
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))


#: Why a run has no trajectory error: one rule for our format and MRCLAM's.
NO_GROUNDTRUTH = (
    "the run has no ground truth (no groundtruth.csv or RobotN_Groundtruth.dat): the filter "
    "started at the nominal pose and only the map is scored, after eq. (17)"
)


@dataclass(frozen=True, eq=False)
class RunSummary:
    """Everything the command line reports about one replay.

    accepted ... deferred: how many sightings had each `Outcome` (fields named by its `label`).
    diagnosis: the replay's self-diagnosis (`ekfslam.core.diagnosis.Diagnosis`), None for a
    result made without one.
    """

    name: str
    alignment: Alignment | None
    start_pose: Array | None
    true_start: Array | None
    landmarks_count: int
    error_unaligned_mean: float | None
    ate_rmse: float | None
    predictions: int
    accepted: int
    rejected: int
    refused: int
    initialised: int
    reinitialised: int
    nis_mean: float | None
    seconds: float
    alignment_note: str | None = None
    ate_note: str | None = None  # why ate_rmse is None (`NO_GROUNDTRUTH`), else None
    singular: int = (
        0  # updates skipped: S singular or not finite (`ekfslam.core.filter.history.Outcome`)
    )
    deferred: int = 0  # first sightings held for a second (a bearing-only sensor)
    diagnosis: Diagnosis | None = None

    def as_dict(self) -> dict:
        """Nested JSON-ready dict (``alignment.x0`` is ``{"alignment": {"x0": ...}}``)."""
        a = self.alignment

        def opt(x):
            return None if x is None or not np.isfinite(x) else float(x)

        return {
            "name": self.name,
            "alignment": None
            if a is None
            else {
                "x0": a.x0,
                "y0": a.y0,
                "theta0": a.theta0,
                "start_pose": [float(v) for v in self.start_pose],
                "mean_error": a.mean_error,
                "rmse": a.rmse,
                "landmarks_matched": len(a.ids),
            },
            "alignment_note": self.alignment_note,
            "true_start": None if self.true_start is None else [float(v) for v in self.true_start],
            "landmarks": {
                "count": self.landmarks_count,
                "error_unaligned_mean": opt(self.error_unaligned_mean),
            },
            "updates": {o.label: getattr(self, o.label) for o in UPDATES_ORDER},
            "predictions": self.predictions,
            "trajectory": {"ate_rmse": opt(self.ate_rmse), "reason": self.ate_note},
            "consistency": {"nis_mean": opt(self.nis_mean)},
            "diagnosis": None if self.diagnosis is None else self.diagnosis.as_dict(),
            "seconds": self.seconds,
        }


def summarize(run: RunLog, result: ReplayResult, method: str = "mean_distance") -> RunSummary:
    """Score a replay against what the run knows: its tag map and its ground truth, if any.

    method : eq. (17)'s objective, "mean_distance" (the seed's) or "least_squares"; anything
        else is refused (it never means "no alignment").
    """
    checks.instance(run, RunLog, "summarize: run", "the run that was replayed")
    checks.instance(result, ReplayResult, "summarize: result", "what ekfslam.replay(run) returned")
    checks.choice(method, "summarize: method", METHODS)
    if result.name != run.meta.name:  # another run's truth would score it with confidence
        warnings.warn(
            f"summarize: the result is a replay of {result.name!r}, scored here against the "
            f"truth of {run.meta.name!r}; pass the run that was replayed",
            stacklevel=2,
        )
    alignment = start_pose = None
    unaligned = None
    note = "the run has no known tag map"
    tag_map = run.meta.tag_map
    if tag_map:
        try:
            alignment = align(result.landmarks, tag_map, method=method)
            note = None
        except AlignmentError as exc:  # not an error of the run: reported, not raised
            note = str(exc)
        if alignment is not None:
            start_pose = alignment.start_pose(run.meta.nominal_start)
        common = [i for i in result.landmarks if i in tag_map]
        if common:
            unaligned = float(
                np.mean([np.linalg.norm(result.landmarks[i] - tag_map[i]) for i in common])
            )
    gt = run.groundtruth
    true_start = None
    ate = None
    ate_note = NO_GROUNDTRUTH if gt is None or not len(gt.t) else None
    if gt is not None and len(gt.t):
        # the truth when the filter starts: MRCLAM's Vicon starts 6-9 s before the odometry
        at_start, inside = interpolate_poses(gt, np.asarray(run.controls.t[:1], dtype=float))
        true_start = at_start[0] if inside.all() else np.asarray(gt.pose[0], dtype=float)
        ate = ate_rmse(result, gt)
    nis = result.history.nis_of_updates
    c = result.counts
    return RunSummary(
        name=result.name,
        alignment=alignment,
        start_pose=start_pose,
        true_start=true_start,
        landmarks_count=len(result.landmarks),
        error_unaligned_mean=unaligned,
        ate_rmse=ate,
        predictions=c.predictions,
        **{o.label: c.of(o) for o in Outcome},
        nis_mean=float(np.mean(nis)) if len(nis) else None,
        seconds=result.seconds,
        alignment_note=note,
        ate_note=ate_note,
        diagnosis=result.diagnosis,
    )


def replay_and_summarize(
    run: RunLog, noise: NoiseConfig, config: FilterConfig
) -> tuple[ReplayResult, RunSummary]:
    """Replay a run with this noise and these filter options and score it (`summarize`).

    What the live tuner computes for each setting (`ekfslam.ui.tuning.Tuner`'s default compute).
    """
    result = replay(run, noise, config)
    return result, summarize(run, result)
