"""Cutting a run: the same log without its detections, or only up to a time.

These are the pieces the notebooks and the lap statistics replay: `without_detections` is dead
reckoning (eqs. 6, 9 alone), `truncate` is the log as it stood at a moment of the drive.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ekfslam.logs.runlog import Controls, Detections, GroundTruth, RunLog


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
        t=d.t[seen],
        tag_id=d.tag_id[seen],
        range=d.range[seen],
        bearing=d.bearing[seen],
        sigma_range=None if d.sigma_range is None else d.sigma_range[seen],
        sigma_bearing=None if d.sigma_bearing is None else d.sigma_bearing[seen],
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
