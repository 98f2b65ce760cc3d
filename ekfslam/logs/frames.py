"""Runs logged as camera frames, on disk: frames.csv and the frames as a video or as images.

A run of camera frames is an ordinary run folder (``data/README.md``) whose run.json has
``camera`` (intrinsics, distortion), ``tags`` (printed size) and ``frames``, plus:

    frames.mp4        the frames as a video: ``"frames": {"kind": "video", "file": "frames.mp4"}``
    frames/000000.png or one image per frame: ``{"kind": "images", "file": "frames/%06d.png"}``
    frames.csv        ``t,frame``: each frame's time (s) and its index in the video / image pattern

Videos are written as MPEG-4 part 2 (``mp4v``), the one compact codec every
``opencv-python-headless`` wheel can write: H.264 writers do not open there. Rendering a
simulated run's frames and detecting the tags in them is `ekfslam.vision.frames_run`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.errors import InputError
from ekfslam.files import atomic_write, atomic_write_text, not_a_file
from ekfslam.geometry import wrap_angle
from ekfslam.logs.csvtable import read_columns
from ekfslam.logs.runjson import FramesSpec, RunMeta, read_meta
from ekfslam.logs.runlog import DETECTIONS_CSV, RUN_JSON

Array = NDArray[np.float64]

FRAMES_CSV = "frames.csv"
FRAME_COLUMNS = ("t", "frame")
VIDEO_FILE, IMAGE_PATTERN = "frames.mp4", "frames/%06d.png"
VIDEO_FOURCC = "mp4v"


@dataclass(frozen=True, eq=False)
class FrameIndex:
    """frames.csv: t (F,) s, non-decreasing, and frame (F,) indices, increasing, from 0 up."""

    t: Array
    frame: NDArray[np.int64]


def read_frame_index(folder: str | Path) -> FrameIndex:
    """Read and check ``folder/frames.csv``; errors name the line."""
    path = Path(folder) / FRAMES_CSV
    problem = not_a_file(path)
    if problem is not None:
        raise InputError(path, None, f"{problem}; a run with frames needs frames.csv (t,frame)")
    t, frame = read_columns(path, FRAME_COLUMNS)
    bad = [
        (~np.isfinite(t), lambda i: f"t is {float(t[i])!r}: times must be finite"),
        (frame < 0, lambda i: f"frame {int(frame[i])} is negative"),
        (
            np.r_[False, t[1:] < t[:-1]],
            lambda i: f"time {float(t[i])!r} s is before the previous row",
        ),
        (
            np.r_[False, frame[1:] <= frame[:-1]],
            lambda i: f"frame {int(frame[i])} does not increase",
        ),
    ]
    firsts = [(int(np.flatnonzero(m)[0]), describe) for m, describe in bad if m.any()]
    if firsts:  # the earliest bad row wins, as in the other run files
        row, describe = min(firsts, key=lambda hit: hit[0])
        raise InputError(path, row + 2, describe(row))
    return FrameIndex(t, frame)


def iter_frames(
    folder: str | Path, meta: RunMeta, index: FrameIndex
) -> Iterator[NDArray[np.uint8]]:
    """The frames listed in `index`, in order, as 8-bit grayscale (height, width) images."""
    import cv2  # lazy: OpenCV (~20 ms) only to read or write frames, not to sniff a run

    folder = Path(folder)
    spec, camera = meta.frames, meta.camera
    if spec is None or camera is None:
        raise InputError(folder / RUN_JSON, None, 'this run has no "frames" (and "camera")')
    size = (camera.height, camera.width)

    def checked(image: np.ndarray | None, where: Path, k: int) -> NDArray[np.uint8]:
        if image is None:
            raise InputError(where, None, f"cannot read frame {k}")
        if image.ndim == 3:
            image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        if image.shape != size:
            raise InputError(
                where,
                None,
                f"frame {k} is {image.shape[1]}x{image.shape[0]} px, but run.json's "
                f"camera image_size is {camera.width}x{camera.height}",
            )
        return image

    if spec.kind == "images":
        for k in index.frame.tolist():
            path = folder / spec.path(k)
            yield checked(cv2.imread(str(path), cv2.IMREAD_GRAYSCALE), path, k)
        return
    path = folder / spec.file
    problem = not_a_file(path)
    if problem is not None:
        raise InputError(path, None, f"{problem}; run.json's frames.file names this video")
    capture = cv2.VideoCapture(str(path))
    if not capture.isOpened():
        raise InputError(path, None, "OpenCV cannot open this video")
    try:
        k = 0
        for wanted in index.frame.tolist():
            while True:
                ok, image = capture.read()
                if not ok:
                    raise InputError(
                        path,
                        None,
                        f"the video ends after {k} frames, but frames.csv lists frame {wanted}",
                    )
                k += 1
                if k - 1 == wanted:
                    yield checked(image, path, wanted)
                    break
    finally:
        capture.release()


def write_frames(
    folder: str | Path,
    spec: FramesSpec,
    frames: Iterable[NDArray[np.uint8]],
    t: ArrayLike,
    fps: float,
) -> FrameIndex:
    """Write 8-bit grayscale frames as `spec` says, and frames.csv with their times `t` (s)."""
    import cv2  # lazy: OpenCV (~20 ms) only to read or write frames, not to sniff a run

    folder = Path(folder)
    times = np.asarray(t, dtype=float)
    written = [0]

    def video(tmp: Path) -> None:  # to a temporary file, renamed once whole (`atomic_write`)
        writer = None
        try:
            for image in frames:
                if writer is None:
                    height, width = image.shape
                    fourcc = cv2.VideoWriter_fourcc(*VIDEO_FOURCC)
                    writer = cv2.VideoWriter(str(tmp), fourcc, fps, (width, height), False)
                    if not writer.isOpened():
                        raise OSError(f"OpenCV cannot write {VIDEO_FOURCC} video")
                writer.write(image)
                written[0] += 1
        finally:
            if writer is not None:
                writer.release()

    if spec.kind == "images":
        for count, image in enumerate(frames, start=1):
            path = folder / spec.path(count - 1)
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write(path, lambda tmp, im=image: _imwrite(cv2, tmp, im))
            written[0] = count
    else:
        atomic_write(folder / spec.file, video)
    if written[0] != len(times):
        raise ValueError(f"{written[0]} frames but {len(times)} times")
    index = FrameIndex(times, np.arange(written[0], dtype=np.int64))
    rows = [f"{ti!r},{k}" for ti, k in zip(times.tolist(), index.frame.tolist(), strict=True)]
    atomic_write_text(folder / FRAMES_CSV, "\n".join([",".join(FRAME_COLUMNS), *rows]) + "\n")
    return index


def _imwrite(cv2: Any, path: Path, image: NDArray[np.uint8]) -> None:
    if not cv2.imwrite(str(path), image):
        raise OSError(f"OpenCV cannot write the image {path.name}")


# ---------------------------------------------------------------------------------------------
# The camera times of a simulated run


@dataclass(frozen=True, eq=False)
class FrameTimes:
    """Camera frame times t (F,) s and the true robot poses (F, 3) at those times."""

    t: Array
    pose: Array = field(repr=False)


def frame_times(
    groundtruth_t: ArrayLike, groundtruth_pose: ArrayLike, rate_hz: float
) -> FrameTimes:
    """Frames at k / rate_hz over the ground truth's span, poses interpolated from it.

    Linear in x, y and in the unwrapped heading; exact where the ground truth has a sample (a
    simulated run's camera times are among its control times).
    """
    t_gt = np.asarray(groundtruth_t, dtype=float)
    pose = np.asarray(groundtruth_pose, dtype=float)
    k0 = math.ceil(t_gt[0] * rate_hz - 1e-9)
    k1 = math.floor(t_gt[-1] * rate_hz + 1e-9)
    t = np.arange(k0, k1 + 1) / rate_hz
    theta = np.unwrap(pose[:, 2])
    columns = [np.interp(t, t_gt, pose[:, 0]), np.interp(t, t_gt, pose[:, 1])]
    out = np.column_stack([*columns, wrap_angle(np.interp(t, t_gt, theta))])
    return FrameTimes(t, out)


def has_frames_only(folder: str | Path) -> bool:
    """Whether `folder` is a run of camera frames without detections.csv (detect on the fly)."""
    folder = Path(folder)
    if (folder / DETECTIONS_CSV).exists() or not (folder / RUN_JSON).is_file():
        return False
    return read_meta(folder / RUN_JSON).frames is not None
