"""Runs logged as camera frames: store the frames, render them for a simulated run, detect tags.

A run of camera frames is an ordinary run folder (``data/README.md``) whose run.json has
``camera`` (intrinsics, distortion), ``tags`` (printed size) and ``frames``, plus:

    frames.mp4        the frames as a video: ``"frames": {"kind": "video", "file": "frames.mp4"}``
    frames/000000.png or one image per frame: ``{"kind": "images", "file": "frames/%06d.png"}``
    frames.csv        ``t,frame``: each frame's time (s) and its index in the video / image pattern

detections.csv is optional in such a run: ``python -m ekfslam detect RUN --out DIR`` makes a
copy of the run with it (``--in-place`` writes the run's own; `detect_run`), and
``python -m ekfslam run RUN`` without it detects on the fly (`read_frames_run`). Videos are
written as MPEG-4 part 2 (``mp4v``), the one compact codec every ``opencv-python-headless``
wheel can write: H.264 writers do not open there.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.arena import SEED_ARENA, Arena
from ekfslam.core.camera import TAG_SIZE, Camera, TagSpec, pinhole_camera
from ekfslam.errors import InputError
from ekfslam.geometry import wrap_angle
from ekfslam.logs.runjson import FramesSpec, RunMeta, read_meta
from ekfslam.logs.runlog import (
    DETECTIONS_CSV,
    RUN_JSON,
    Detections,
    RunLog,
    read_columns,
    read_run,
    write_detections,
    write_run,
)
from ekfslam.vision.detect import TagObserver, VisionConfig, VisionCounts, observations_table
from ekfslam.vision.render import ArenaRenderer, RenderConfig

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
    if not path.is_file():
        raise InputError(path, None, "missing file; a run with frames needs frames.csv (t,frame)")
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
                where, None, f"frame {k} is {image.shape[1]}x{image.shape[0]} px, but run.json's "
                f"camera image_size is {camera.width}x{camera.height}",
            )  # fmt: skip
        return image

    if spec.kind == "images":
        for k in index.frame.tolist():
            path = folder / spec.path(k)
            yield checked(cv2.imread(str(path), cv2.IMREAD_GRAYSCALE), path, k)
        return
    path = folder / spec.file
    if not path.is_file():
        raise InputError(path, None, "missing video file named by run.json's frames.file")
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
                        path, None, f"the video ends after {k} frames, but frames.csv lists "
                        f"frame {wanted}",
                    )  # fmt: skip
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
    folder = Path(folder)
    times = np.asarray(t, dtype=float)
    writer = None
    count = 0
    try:
        for count, image in enumerate(frames, start=1):
            if spec.kind == "images":
                path = folder / spec.path(count - 1)
                path.parent.mkdir(parents=True, exist_ok=True)
                if not cv2.imwrite(str(path), image):
                    raise OSError(f"cannot write {path}")
                continue
            if writer is None:
                height, width = image.shape
                fourcc = cv2.VideoWriter_fourcc(*VIDEO_FOURCC)
                writer = cv2.VideoWriter(
                    str(folder / spec.file), fourcc, fps, (width, height), False
                )
                if not writer.isOpened():
                    raise OSError(f"OpenCV cannot write {VIDEO_FOURCC} video to {spec.file}")
            writer.write(image)
    finally:
        if writer is not None:
            writer.release()
    if count != len(times):
        raise ValueError(f"{count} frames but {len(times)} times")
    index = FrameIndex(times, np.arange(count, dtype=np.int64))
    rows = [f"{ti!r},{k}" for ti, k in zip(times.tolist(), index.frame.tolist(), strict=True)]
    (folder / FRAMES_CSV).write_text("\n".join([",".join(FRAME_COLUMNS), *rows]) + "\n")
    return index


# ---------------------------------------------------------------------------------------------
# Simulated runs with frames


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


def with_camera(
    run: RunLog,
    camera: Camera | None = None,
    tags: TagSpec | None = None,
    mounting: ArrayLike | None = None,
    kind: str = "video",
    name: str | None = None,
) -> RunLog:
    """`run` as a run of camera frames: camera, tags and frames in its metadata, no detections.

    Defaults: the run's own camera, tags and mounting; for a simulated run without a camera in
    its metadata, the camera and tags its simulator saw with (so that its frames show the tags
    its simulated detections saw), else `ekfslam.core.camera.pinhole_camera()` and 0.16 m tags; a
    video.
    """
    from ekfslam.sim.simulation import config_from_dict

    spec = FramesSpec(kind, VIDEO_FILE if kind == "video" else IMAGE_PATTERN)  # type: ignore[arg-type]
    sim = (run.meta.simulation or {}).get("config")
    seen_with = config_from_dict(sim) if sim is not None else None
    if camera is None:
        camera = run.meta.camera or (seen_with.camera if seen_with else pinhole_camera())
    if tags is None:
        tags = run.meta.tags or (seen_with.tags if seen_with else TagSpec(TAG_SIZE))
    meta = dataclasses.replace(
        run.meta,
        name=name or run.meta.name,
        camera=camera,
        tags=tags,
        frames=spec,
        camera_mounting=np.asarray(
            run.meta.camera_mounting if mounting is None else mounting, dtype=float
        ),
    )
    empty = Detections(np.empty(0), np.empty(0, np.int64), np.empty(0), np.empty(0))
    return dataclasses.replace(run, meta=meta, detections=empty)


def write_frames_run(
    run: RunLog,
    folder: str | Path,
    *,
    render: RenderConfig | None = None,
    arena: Arena = SEED_ARENA,
    overwrite: bool = False,
) -> FrameIndex:
    """Render the frames of a run of camera frames (see `with_camera`) and write the run.

    The frames are the camera's view from the ground-truth pose at every k / camera_hz, drawn
    by `ekfslam.vision.render.ArenaRenderer` (frame k's noise seeded by k). The run must have ground
    truth, a camera rate and camera metadata; detections.csv is not written.
    """
    meta = run.meta
    if meta.frames is None or meta.camera is None or meta.tags is None:
        raise ValueError("give the run a camera first: write_frames_run(with_camera(run), ...)")
    if run.groundtruth is None or meta.camera_rate_hz is None:
        raise ValueError("rendering frames needs the run's ground truth and camera rate")
    if meta.tag_map is not None and meta.tag_map.keys() != arena.tag_map().keys():
        raise ValueError("the run's tag map is not the arena's: render it with its own arena")
    folder = Path(folder)
    write_run(run, folder, overwrite=overwrite, with_detections=False)
    renderer = ArenaRenderer(meta.camera, meta.tags, meta.camera_mounting, arena, render)
    times = frame_times(run.groundtruth.t, run.groundtruth.pose, meta.camera_rate_hz)
    frames = (renderer.render(pose, k) for k, pose in enumerate(times.pose))
    return write_frames(folder, meta.frames, frames, times.t, meta.camera_rate_hz)


# ---------------------------------------------------------------------------------------------
# Frames -> detections


def detect_frames(
    folder: str | Path, meta: RunMeta | None = None, config: VisionConfig | None = None
) -> tuple[Detections, VisionCounts]:
    """Detect the tags in every frame of a run: (detections, counts of what was refused)."""
    folder = Path(folder)
    meta = meta if meta is not None else read_meta(folder / RUN_JSON)
    if meta.frames is None or meta.camera is None or meta.tags is None:
        raise InputError(
            folder / RUN_JSON, None, 'no camera frames: run.json needs "frames", "camera", "tags"'
        )
    index = read_frame_index(folder)
    ids = None if meta.tag_map is None else meta.tag_map.keys()
    observer = TagObserver(meta.camera, meta.tags, meta.camera_mounting, ids, config)
    results = [observer.observe(image) for image in iter_frames(folder, meta, index)]
    t, tag_id, rng, bearing = observations_table(index.t.tolist(), results)
    return Detections(t, tag_id, rng, bearing), observer.counts


def has_frames_only(folder: str | Path) -> bool:
    """Whether `folder` is a run of camera frames without detections.csv (detect on the fly)."""
    folder = Path(folder)
    if (folder / DETECTIONS_CSV).exists() or not (folder / RUN_JSON).is_file():
        return False
    return read_meta(folder / RUN_JSON).frames is not None


#: Why `ekfslam.vision.detect.TagObserver` refuses a tag it found, by refusal reason.
REFUSAL_REASONS = {
    "nonfinite": "range or bearing not finite",
    "unknown_id": "id not in the tag map",
    "duplicate_id": "id seen twice in one frame",
    "outside_frame": "outline not wholly in the image",
    "edge_on": "seen too edge-on",
}


@dataclass(frozen=True)
class FramesReport:
    """What detecting a run's frames found, kept and refused (``run`` prints it)."""

    counts: VisionCounts

    def as_dict(self) -> dict:
        """``loaded`` (frames, tags found, detections kept) and ``dropped`` (count, reason)."""
        c = self.counts
        return {
            "loaded": {"frames": c.frames, "tags_found": c.found, "detections": c.accepted},
            "dropped": {
                reason: {"count": int(c.refused.get(reason, 0)), "reason": why}
                for reason, why in REFUSAL_REASONS.items()
            },
        }

    def lines(self) -> tuple[str, str]:
        """ "loaded: ..." (frames, tags found, detections kept) and "dropped: ..." (what, why)."""
        c = self.counts
        dropped = [
            f"{d['count']} {name.replace('_', ' ')} ({d['reason']})"
            for name, d in self.as_dict()["dropped"].items()
            if d["count"]
        ]
        return (
            f"loaded: {c.frames} frames, {c.found} tags found, {c.accepted} detections kept",
            "dropped: " + (", ".join(dropped) if dropped else "nothing"),
        )


def read_frames_run(
    folder: str | Path, config: VisionConfig | None = None
) -> tuple[RunLog, FramesReport]:
    """Read a run of camera frames with detections made from its frames (not detections.csv)."""
    folder = Path(folder)
    detections, counts = detect_frames(folder, config=config)
    return read_run(folder, detections=detections), FramesReport(counts)


def detect_run(
    folder: str | Path,
    out: str | Path | None = None,
    config: VisionConfig | None = None,
    overwrite: bool = False,
    *,
    in_place: bool = False,
) -> tuple[Path, VisionCounts]:
    """Detect the tags in a run's frames and write them; returns what was written, and counts.

    `out` ending in ``.csv`` is written as that detections file. Any other `out` is a new run
    folder: a copy of the run (frames included) with the detections.csv, so the original run
    still replays from its frames. ``in_place=True`` (and no `out`) writes the run's own
    detections.csv, which ``run`` then reads instead of the frames. Nothing existing is replaced
    without `overwrite`; nothing is written unless the frames were all read.
    """
    folder = Path(folder)
    meta = read_meta(folder / RUN_JSON)
    if out is not None and in_place:
        raise InputError(folder, None, "give --out or --in-place, not both")
    if out is None and not in_place:
        raise InputError(
            folder, None, "say where to write the detections: --out DIR (a new run folder), "
            "--out FILE.csv, or --in-place (this run's detections.csv, which `run` then uses "
            "instead of the frames)",
        )  # fmt: skip
    if in_place:
        target = path = folder / DETECTIONS_CSV
    elif Path(out).suffix.lower() == ".csv":
        target = path = Path(out)
    else:
        target, path = Path(out), Path(out) / DETECTIONS_CSV
        if target.resolve().is_relative_to(folder.resolve()):
            raise InputError(target, None, "is inside the run; use --in-place to write into it")
    if target.is_dir() and target != path and any(target.iterdir()) and not overwrite:
        raise InputError(target, None, "folder exists and is not empty; pass --overwrite")
    if path.exists() and not overwrite:
        raise InputError(path, None, "exists; pass --overwrite to replace it")
    detections, counts = detect_frames(folder, meta, config)
    if target != path:  # a new run folder: the run's own files, then its detections
        shutil.copytree(folder, target, dirs_exist_ok=True)
    else:  # a FILE.csv: its folder is made only once there is something to write into it
        path.parent.mkdir(parents=True, exist_ok=True)
    return write_detections(detections, path, meta.tag_map), counts
