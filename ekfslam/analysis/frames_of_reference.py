"""The frame the filter works in, and the truth expressed in it.

The filter starts at the run's nominal start while the robot stood at its true start (the ground
truth's first pose), so the filter's map is the world seen from a frame in which the true start
sits at the nominal one. Expressing the truth in that frame compares estimate and truth with no
fitting at all (eq. 17's alignment fits the same transform from the map instead).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ekfslam.analysis.evaluation import interpolate_poses
from ekfslam.core.filter.history import History
from ekfslam.errors import EkfSlamError
from ekfslam.geometry import compose, invert, transform_points
from ekfslam.logs.runlog import GroundTruth, RunLog

Array = NDArray[np.float64]


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
