"""The typical wrong replay loops of exercise 8 (notebook 06), replayed to name the student's one.

When a student's loop does not reproduce `ekfslam.replay`, `diagnose` runs the package's loop
once with each typical mistake and returns the description of the first whose final state equals
the student's to 1e-9: so the check can say "your numbers are those of a loop that ..." without
showing any code. Each mistake is one flag on `mistaken_loop`, the loop of eqs. (4)-(16) that
`ekfslam.pipeline.replay` runs (each piece of a control interval one prediction with
R = V (M dt) Vᵀ, eq. 9; each detection one update, eqs. 10-16, once the pose is predicted up to
its time).

The filter the check hands the student is `ekfslam.analysis.watched_filter.WatchedEKF` (kept
apart: a graded sandbox holds it, and not this module, whose loop is the exercise's answer).
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.models import motion_noise
from ekfslam.core.noise import NoiseConfig, default_config
from ekfslam.logs.runlog import RunLog
from ekfslam.teaching.verdicts import close

#: mistake -> what a loop with it does, as the check tells it (the typical ones, in this order)
MISTAKES = {
    "whole": "predicts each control interval whole and only then applies the detections inside "
    "it: split the interval at each detection, predict up to the detection's time, apply it, "
    "then predict on to the end of the interval.",
    "early": "applies each detection before the pose is predicted up to its time (the update "
    "comes before the prediction that reaches it): split the interval at the detection, "
    "predict up to its time first, then update.",
    "unscaled": "builds each piece's R from M itself: M is a noise density per second, so a "
    "piece of length dt has R = V (M dt) Vᵀ (eq. 9).",
    "twice": "feeds each tag's first sighting twice: ekf.update already places a new landmark "
    "(eq. 12), and correcting it with the same sighting counts that sighting twice.",
    "stops": "stops at the last detection: after it the robot drives on to the last control, "
    "and those predictions move the pose and grow its covariance.",
}


def mistaken_loop(run: RunLog, ekf: EKFSLAM, noise: NoiseConfig, mistake: str | None) -> None:
    """The replay loop of eqs. (4)-(16) over `run`, with one of `MISTAKES` (None: none, the loop
    `ekfslam.replay` runs)."""
    if mistake is not None and mistake not in MISTAKES:
        raise ValueError(f"unknown mistake {mistake!r}; known: {', '.join(MISTAKES)}")
    twist, t_ctrl, det = run.control_twist(), run.controls.t, run.detections
    M, Q = noise.motion_density(), noise.Q
    times = t_ctrl if mistake == "whole" else np.unique(np.concatenate([t_ctrl, det.t]))
    if mistake == "stops" and len(det.t):
        times = times[times <= det.t[-1]]
    seen: set[int] = set()
    k = 0  # the next detection

    def sight_until(t: float) -> None:
        nonlocal k
        while k < len(det.t) and det.t[k] <= t:
            tag, z = int(det.tag_id[k]), (det.range[k], det.bearing[k])
            ekf.update(tag, z, Q, det.t[k])
            if mistake == "twice" and tag not in seen:
                ekf.update(tag, z, Q, det.t[k])
            seen.add(tag)
            k += 1

    for start, end in pairwise(times):
        if mistake not in ("whole", "early"):
            sight_until(start)  # the pose is predicted up to these detections' times
        elif mistake == "early":
            sight_until(end)  # applied at the pose of the piece's start
        row = np.searchsorted(t_ctrl, start, side="right") - 1  # the control row in force
        if row >= 0:  # before the first control the robot stands still
            dt = end - start
            density = M if mistake == "unscaled" else M * dt
            ekf.predict(twist[row] * dt, motion_noise(ekf.mu[:3], density), end)
        if mistake == "whole":
            sight_until(end)
    sight_until(np.inf)  # the detections at (or, for "stops", after) the last time


def diagnose(run: RunLog, noise: NoiseConfig, mu: np.ndarray, predictions: int) -> str | None:
    """The description in `MISTAKES` of the first typical loop whose final mean and number of
    predictions are the student's (to 1e-9), or None when none is."""
    for mistake, what in MISTAKES.items():
        ekf = EKFSLAM(run.meta.nominal_start, None, default_config(run))
        mistaken_loop(run, ekf, noise, mistake)
        if ekf.counts.predictions == predictions and ekf.mu.shape == mu.shape and close(ekf.mu, mu):
            return what
    return None
