"""Runs of camera frames made and read: render a simulated run's frames, detect their tags.

The storage of such a run (frames.csv, the video or images) is `ekfslam.logs.frames`; this
module joins it to the camera models of `ekfslam.vision`. `with_camera` turns a run into a run
of camera frames (camera, tags and frames in its metadata, no detections), `write_frames_run`
renders its frames with `ekfslam.vision.render.ArenaRenderer`, and `detect_frames` finds the
AprilTags in a run's frames with `ekfslam.vision.detect.TagObserver`. detections.csv is
optional in a run of frames: ``python -m ekfslam detect RUN --out DIR`` makes a copy of the run
with it (``--in-place`` writes the run's own; `detect_run`), and ``python -m ekfslam run RUN``
without it detects on the fly (`read_frames_run`).

The one module of `ekfslam.vision` that reads and writes run logs (ARCHITECTURE.md: vision may
import logs, as sim does, because these functions take and give a `RunLog`).
"""

from __future__ import annotations

import dataclasses
import math
import shutil
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ekfslam import checks
from ekfslam.core.arena import SEED_ARENA, Arena
from ekfslam.core.camera import TAG_SIZE, Camera, TagSpec, pinhole_camera
from ekfslam.errors import ConfigError, InputError
from ekfslam.files import new_folder, probe_output
from ekfslam.logs.frames import (
    IMAGE_PATTERN,
    VIDEO_FILE,
    FrameIndex,
    frame_times,
    iter_frames,
    read_frame_index,
    write_frames,
)
from ekfslam.logs.runjson import FramesSpec, RunMeta, read_meta
from ekfslam.logs.runlog import (
    DETECTIONS_CSV,
    RUN_JSON,
    Detections,
    RunLog,
    read_run,
    write_detections,
    write_run,
)
from ekfslam.vision.detect import TagObserver, VisionConfig, VisionCounts, observations_table
from ekfslam.vision.render import ArenaRenderer, RenderConfig

# ---------------------------------------------------------------------------------------------
# Simulated runs with frames


def simulated_view(meta: RunMeta) -> tuple[Camera, TagSpec] | None:
    """The camera and printed tags a simulated run's detections were made with, or None.

    Read from the simulator's config recorded in ``meta.simulation["config"]`` (the dict of
    `ekfslam.sim.simulation.SimulationConfig.to_dict`, decoded here as its `config_from_dict`
    does, so that vision need not load the simulator): ``camera`` as a `Camera`; a config
    written before the simulator had a camera model names only ``camera_fov`` (rad), the
    default camera with that horizontal field of view; neither, the default camera. None for a
    run without a recorded simulator config.
    """
    config: Mapping[str, Any] | None = (meta.simulation or {}).get("config")
    if config is None:
        return None
    if isinstance(config.get("camera"), dict):
        camera = Camera(**config["camera"])
    elif config.get("camera_fov") is not None:
        camera = pinhole_camera(horizontal_fov_deg=math.degrees(config["camera_fov"]))
    else:
        camera = pinhole_camera()
    return camera, TagSpec(config.get("tag_size", TAG_SIZE))


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
    spec = FramesSpec(kind, VIDEO_FILE if kind == "video" else IMAGE_PATTERN)  # type: ignore[arg-type]
    seen_with = simulated_view(run.meta)
    if camera is None:
        camera = run.meta.camera or (seen_with[0] if seen_with else pinhole_camera())
    if tags is None:
        tags = run.meta.tags or (seen_with[1] if seen_with else TagSpec(TAG_SIZE))
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
    checks.instance(run, RunLog, "write_frames_run: run")
    meta = run.meta
    if meta.frames is None or meta.camera is None or meta.tags is None:
        raise ConfigError("give the run a camera first: write_frames_run(with_camera(run), ...)")
    if run.groundtruth is None or meta.camera_rate_hz is None:
        raise ConfigError(
            f"run {meta.name!r}: rendering frames needs the run's ground truth and camera rate"
        )
    if meta.tag_map is not None and meta.tag_map.keys() != arena.tag_map().keys():
        raise ConfigError("the run's tag map is not the arena's: render it with its own arena")
    folder = checks.path(folder, "write_frames_run: folder")
    renderer = ArenaRenderer(meta.camera, meta.tags, meta.camera_mounting, arena, render)
    times = frame_times(run.groundtruth.t, run.groundtruth.pose, meta.camera_rate_hz)
    frames = (renderer.render(pose, k) for k, pose in enumerate(times.pose))
    with new_folder(folder):  # a failed or interrupted rendering leaves no half-made run
        write_run(run, folder, overwrite=overwrite, with_detections=False)
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
            folder,
            None,
            "say where to write the detections: --out DIR (a new run folder), "
            "--out FILE.csv, or --in-place (this run's detections.csv, which `run` then uses "
            "instead of the frames)",
        )
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
    probe_output(path)  # before the frames are read: a target that cannot be written says so now
    detections, counts = detect_frames(folder, meta, config)
    with new_folder(target if target != path else path.parent):  # removed if interrupted
        if target != path:  # a new run folder: the run's own files, then its detections
            shutil.copytree(folder, target, dirs_exist_ok=True)
        return write_detections(detections, path, meta.tag_map), counts
