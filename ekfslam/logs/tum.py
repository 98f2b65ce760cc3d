"""Export trajectories and maps in the TUM format, so that `evo` can score them.

The TUM RGB-D benchmark's trajectory format is one pose per line::

    timestamp x y z qx qy qz qw

with the time in s, the position in m and the orientation as a unit quaternion (scalar last).
Our poses are planar (x, y, θ), so z = 0 and the quaternion is a rotation about z:
(qx, qy, qz, qw) = (0, 0, sin(θ/2), cos(θ/2)).

A map has no time. We write one line per landmark with its id in the timestamp column, z = 0 and
the identity orientation, so that `evo`, which pairs poses by timestamp, pairs landmarks by id::

    evo_ape tum groundtruth.tum trajectory.tum              # ATE against the truth, no alignment
    evo_ape tum map_truth.tum map.tum --align               # map error after an SE(3) fit

(``--align`` minimises squared distances: it is the least-squares cousin of the seed's eq. 17.)
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter.history import History
from ekfslam.errors import InputError
from ekfslam.files import (
    atomic_write_all,
    atomic_write_text,
    new_folder,
    not_a_file,
    probe_output,
)
from ekfslam.geometry import wrap_angle
from ekfslam.logs.runlog import GroundTruth, RunLog


class ReplayLike(Protocol):
    """What `export_tum` reads of a replay (`ekfslam.pipeline.ReplayResult` has it): the history
    of estimates and the final map. A protocol, so that a log format does not depend on the
    filter that produced the estimate."""

    history: History
    landmarks: Mapping[int, Any]


Array = NDArray[np.float64]

#: Names of the files `export_tum` writes into its folder.
TRAJECTORY, GROUNDTRUTH, MAP, MAP_TRUTH = (
    "trajectory.tum",
    "groundtruth.tum",
    "map.tum",
    "map_truth.tum",
)


def poses_to_tum(t: ArrayLike, poses: ArrayLike) -> Array:
    """Planar poses as TUM rows.

    Parameters
    ----------
    t : (K,) s.
    poses : (K, 3) (x, y, θ) in m, m, rad.

    Returns
    -------
    (K, 8) rows (t, x, y, 0, 0, 0, sin(θ/2), cos(θ/2)).
    """
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if len(t) != len(poses):
        raise ValueError(f"{len(t)} times but {len(poses)} poses")
    half = 0.5 * poses[:, 2]
    zeros = np.zeros(len(t))
    return np.column_stack(
        [t, poses[:, 0], poses[:, 1], zeros, zeros, zeros, np.sin(half), np.cos(half)]
    )


def last_pose_per_time(t: ArrayLike, poses: ArrayLike) -> tuple[Array, Array]:
    """Keep, for every distinct time, the last pose recorded at it.

    The filter records a prediction and then an update at the same time; `evo` needs strictly
    increasing timestamps, and the pose after the update is the estimate at that time.

    Returns (t (K',), poses (K', 3)), t strictly increasing (times are sorted first, stably).
    """
    t = np.asarray(t, dtype=np.float64).reshape(-1)
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    order = np.argsort(t, kind="stable")
    t, poses = t[order], poses[order]
    last = np.append(t[1:] != t[:-1], True) if len(t) else np.zeros(0, dtype=bool)
    return t[last], poses[last]


def landmarks_to_tum(landmarks: Mapping[int, ArrayLike]) -> Array:
    """A map as TUM rows (id, x, y, 0, 0, 0, 0, 1), sorted by id; see the module docstring."""
    ids = sorted(int(i) for i in landmarks)
    xy = np.array([np.asarray(landmarks[i], dtype=np.float64) for i in ids]).reshape(-1, 2)
    return poses_to_tum(np.array(ids, dtype=np.float64), np.column_stack([xy, np.zeros(len(ids))]))


def write_tum(path: str | os.PathLike, rows: ArrayLike) -> Path:
    """Write TUM rows (K, 8) to `path`, one line each, numbers printed to round-trip exactly.

    Times are printed with ``repr`` (shortest exact text), so Unix times such as 1248446188.323
    keep their milliseconds.
    """
    path = Path(path)
    return atomic_write_text(path, tum_text(path, rows))


def tum_text(path: Path, rows: ArrayLike) -> str:
    """The text of TUM rows (K, 8), one line each (`write_tum`); `path` names them in errors."""
    rows = np.asarray(rows, dtype=np.float64).reshape(-1, 8)
    if not np.isfinite(rows).all():
        raise ValueError(f"{path}: non-finite values cannot be written in the TUM format")
    return "".join(" ".join(repr(v) for v in row) + "\n" for row in rows.tolist())


def read_tum(path: str | os.PathLike) -> tuple[Array, Array]:
    """Read a planar TUM file back: (t (K,), poses (K, 3) as (x, y, θ)).

    Lines starting with ``#`` and blank lines are skipped. θ is the yaw of the quaternion,
    wrapped to [-π, π). A line that is not 8 numbers, or a quaternion that is not a rotation about
    z (|qx|, |qy| or |z| above 1e-6 after normalising), raises `InputError` naming the line.
    """
    path = Path(path)
    problem = not_a_file(path)  # before reading: a FIFO would block for ever
    if problem is not None:
        raise InputError(path, None, problem)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(path, None, f"cannot read the file: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise InputError(path, None, f"not UTF-8 text (byte {exc.start}); save as UTF-8") from None
    rows = []
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        if len(fields) != 8:
            raise InputError(
                path, number, f"expected 8 numbers (t x y z qx qy qz qw), found {len(fields)}"
            )
        try:
            values = [float(f) for f in fields]
        except ValueError:
            raise InputError(path, number, "not a number: " + " ".join(fields)) from None
        if not all(math.isfinite(v) for v in values):
            raise InputError(path, number, "every value must be finite")
        q = np.array(values[4:])
        norm = float(np.linalg.norm(q))
        if norm == 0.0:
            raise InputError(path, number, "the quaternion is zero")
        qx, qy, qz, qw = q / norm
        if max(abs(qx), abs(qy), abs(values[3])) > 1e-6:
            raise InputError(path, number, "not a planar pose: z, qx and qy must be 0")
        rows.append((values[0], values[1], values[2], 2.0 * math.atan2(qz, qw)))
    table = np.array(rows, dtype=np.float64).reshape(-1, 4)
    poses = table[:, 1:].copy()
    poses[:, 2] = wrap_angle(poses[:, 2])
    return table[:, 0].copy(), poses


def export_tum(run: RunLog, result: ReplayLike, folder: str | os.PathLike) -> dict[str, Path]:
    """Write a replay's trajectory and map, and the run's truth where it has one, as TUM files.

    Files (in `folder`, created if needed): ``trajectory.tum`` (the estimate after every event,
    the last one at each time), ``map.tum`` (the estimated landmarks), and when known
    ``groundtruth.tum`` (the run's ground-truth poses) and ``map_truth.tum`` (its tag map).

    Returns {file name: path} of the files written.
    """
    folder = probe_output(folder, folder=True)
    h = result.history
    t, poses = last_pose_per_time(h.t, h.pose)
    rows = {TRAJECTORY: poses_to_tum(t, poses), MAP: landmarks_to_tum(result.landmarks)}
    gt: GroundTruth | None = run.groundtruth
    if gt is not None and len(gt.t):
        gt_t, gt_pose = last_pose_per_time(gt.t, gt.pose)
        rows[GROUNDTRUTH] = poses_to_tum(gt_t, gt_pose)
    if run.meta.tag_map:
        rows[MAP_TRUTH] = landmarks_to_tum(run.meta.tag_map)
    texts = {name: tum_text(folder / name, r) for name, r in rows.items()}
    with new_folder(folder):  # the files together or none of them, even when interrupted
        paths = atomic_write_all(
            {folder / name: (lambda tmp, s=text: tmp.write_text(s)) for name, text in texts.items()}
        )
    return dict(zip(texts, paths, strict=True))
