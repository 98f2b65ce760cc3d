"""How good is range and bearing from pixels? Rendered frames at random poses, scored against truth.

``python -m ekfslam vision-eval`` renders the seed's arena from random robot poses
(`ekfslam.vision.render`), runs the vision pipeline (`ekfslam.vision.detect`) on each frame and
prints:

- the detection rate over tags fully in view and facing the camera (incidence <= 60 degrees;
  `ekfslam.core.camera.tags_in_view`, the rule the simulator sees by), and the number of accepted
  detections whose id is wrong (its corners are not that tag's);
- range and bearing errors (median and standard deviation) by distance band;
- the time of detection plus pose for one frame (median wall-clock and CPU);
- with ``--run RUN`` (a simulated run of camera frames): the map error (eq. 17) of the run
  replayed from its frames against the same run replayed from the simulator's exact detections
  (`compare_replays`).

The issue's targets are printed beside the figures.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.analysis.evaluation import interpolate_poses, summarize
from ekfslam.core.arena import SEED_ARENA, Arena
from ekfslam.core.camera import (
    DEFAULT_MOUNTING,
    TAG_SIZE,
    Camera,
    TagSpec,
    pinhole_camera,
    tags_in_view,
)
from ekfslam.core.noise import default_noise
from ekfslam.geometry import wrap_angle
from ekfslam.logs.runjson import read_meta
from ekfslam.logs.runlog import Detections, RunLog
from ekfslam.pipeline import replay
from ekfslam.sim.simulation import config_from_dict, simulate
from ekfslam.vision.detect import TagObserver, VisionConfig, VisionCounts
from ekfslam.vision.frames_run import read_frames_run
from ekfslam.vision.render import ArenaRenderer, RenderConfig

Array = NDArray[np.float64]

#: Distance bands (m) the errors are reported in.
BANDS = (0.2, 0.5, 0.8, 1.1, 1.4, 2.2)
#: The issue's targets.
TARGETS = {
    "detection_rate": 0.98,
    "range_median_m": 0.002,
    "range_std_m": 0.005,
    "bearing_std_rad": math.radians(0.05),
    "frame_ms": 15.0,
    "replay_ratio": 1.2,
}


@dataclass(frozen=True)
class BandStats:
    """Errors of the accepted detections whose true range is in [low, high) m.

    Medians and standard deviations of range error (m) and bearing error (rad).
    """

    low: float
    high: float
    count: int
    range_median: float
    range_std: float
    bearing_median: float
    bearing_std: float


@dataclass(frozen=True, eq=False)
class VisionEvaluation:
    """The scores of `evaluate_vision`.

    in_view : tags fully in view and facing the camera; detected : how many of them were
    accepted. wrong_ids : accepted detections whose id is not the tag at those corners.
    true_range, range_error, bearing_error : (M,) per accepted detection, m, m, rad.
    frame_ms, cpu_ms : (F,) detection + pose time per frame, wall-clock and CPU.
    """

    poses: int
    in_view: int
    detected: int
    wrong_ids: int
    true_range: Array
    range_error: Array
    bearing_error: Array
    frame_ms: Array
    cpu_ms: Array
    counts: VisionCounts
    config: VisionConfig

    @property
    def detection_rate(self) -> float:
        return self.detected / self.in_view if self.in_view else math.nan

    def bands(self, edges: ArrayLike = BANDS) -> tuple[BandStats, ...]:
        """Errors by distance band."""
        e = np.asarray(edges, dtype=float)
        out = []
        for low, high in itertools.pairwise(e):
            m = (self.true_range >= low) & (self.true_range < high)
            r, b = self.range_error[m], self.bearing_error[m]
            stats = [np.median(r), np.std(r), np.median(b), np.std(b)] if m.any() else [np.nan] * 4
            out.append(BandStats(float(low), float(high), int(m.sum()), *map(float, stats)))
        return tuple(out)

    def targets(self) -> dict[str, bool]:
        """Each target of the issue: met or not."""
        bands = [b for b in self.bands() if b.count > 0]
        return {
            "detected >= 98%": self.detection_rate >= TARGETS["detection_rate"],
            "no wrong ids": self.wrong_ids == 0,
            "|range median| <= 2 mm in every band": all(
                abs(b.range_median) <= TARGETS["range_median_m"] for b in bands
            ),
            "range std <= 5 mm in every band": all(
                b.range_std <= TARGETS["range_std_m"] for b in bands
            ),
            "bearing std <= 0.05 deg": float(np.std(self.bearing_error))
            <= TARGETS["bearing_std_rad"],
            "median time <= 15 ms": float(np.median(self.frame_ms)) <= TARGETS["frame_ms"],
        }


def random_poses(n: int, seed: int = 0, arena: Arena = SEED_ARENA, margin: float = 0.15) -> Array:
    """(n, 3) poses uniform over the arena (at least `margin` m from the walls), any heading."""
    rng = np.random.default_rng(seed)
    half = arena.half_size - margin
    return np.column_stack([rng.uniform(-half, half, (n, 2)), rng.uniform(-np.pi, np.pi, n)])


def evaluate_vision(
    poses: int | ArrayLike = 200,
    seed: int = 0,
    camera: Camera | None = None,
    tags: TagSpec | None = None,
    mounting: ArrayLike = DEFAULT_MOUNTING,
    render: RenderConfig | None = None,
    config: VisionConfig | None = None,
    facing: float = math.radians(60.0),
    arena: Arena = SEED_ARENA,
) -> VisionEvaluation:
    """Render frames at `poses` (or that many random poses), detect, and score against truth.

    facing : rad, a tag counts as facing the camera up to this incidence.
    """
    camera = camera if camera is not None else pinhole_camera()
    tags = tags if tags is not None else TagSpec(TAG_SIZE)
    config = config if config is not None else VisionConfig()
    P = random_poses(poses, seed, arena) if isinstance(poses, int) else np.asarray(poses, float)
    P = P.reshape(-1, 3)
    renderer = ArenaRenderer(camera, tags, mounting, arena, render)
    ready_all = tags_in_view(
        camera,
        tags,
        mounting,
        P,
        arena.tag_positions(),
        arena.tag_normals(),
        tag_height=renderer.config.tag_height,
        max_incidence=facing,
    )
    observer = TagObserver(camera, tags, mounting, arena.tag_ids.tolist(), config)
    in_view = detected = wrong = 0
    rows, wall, cpu = [], [], []
    for k, pose in enumerate(P):
        frame = renderer.render(pose, k)
        truth = renderer.truth(pose)
        w0, c0 = time.perf_counter(), time.process_time()
        result = observer.observe(frame)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
        seen = {o.tag_id: o for o in result.observations}
        ready = ready_all[k]
        in_view += int(ready.sum())
        detected += sum(int(i) in seen for i in truth.tag_id[ready])
        for tag_id, o in seen.items():
            j = int(np.flatnonzero(truth.tag_id == tag_id)[0])
            size = (
                np.ptp(truth.corners[j], axis=0).max() if np.isfinite(truth.corners[j]).all() else 0
            )
            if not np.abs(o.corners - truth.corners[j]).max() <= 0.1 * size + 2.0:
                wrong += 1  # NaN truth (the tag is not in front of the camera) counts too
                continue
            rows.append(
                (truth.range[j], o.range - truth.range[j], wrap_angle(o.bearing - truth.bearing[j]))
            )
    r = np.array(rows, dtype=float).reshape(-1, 3)
    return VisionEvaluation(
        poses=len(P),
        in_view=in_view,
        detected=detected,
        wrong_ids=wrong,
        true_range=r[:, 0],
        range_error=r[:, 1],
        bearing_error=r[:, 2],
        frame_ms=1e3 * np.array(wall),
        cpu_ms=1e3 * np.array(cpu),
        counts=observer.counts,
        config=config,
    )


def format_evaluation(ev: VisionEvaluation) -> str:
    """The table that ``vision-eval`` prints."""
    c = ev.config
    refine = "edge refinement" if c.refine else "the detector's own corners"
    lines = [
        f"{ev.poses} random poses in the seed's arena; detector {c.detector} with {refine}",
        f"detected {ev.detected}/{ev.in_view} tags fully in view and facing the camera "
        f"({100 * ev.detection_rate:.1f}%); wrong ids passed on: {ev.wrong_ids}",
        "refused: "
        + ", ".join(f"{k} {v}" for k, v in ev.counts.refused.items())
        + f" (of {ev.counts.found} found)",
        f"{'distance':>10}{'n':>6}{'range median':>15}{'range std':>12}"
        f"{'bearing median':>17}{'bearing std':>14}",
    ]
    for b in ev.bands():
        lines.append(
            f"{f'{b.low:.1f}-{b.high:.1f} m':>10}{b.count:>6}{1e3 * b.range_median:>+12.2f} mm"
            f"{1e3 * b.range_std:>9.2f} mm{math.degrees(b.bearing_median):>+13.4f} deg"
            f"{math.degrees(b.bearing_std):>10.4f} deg"
        )
    lines.append(
        f"{'all':>10}{len(ev.range_error):>6}{1e3 * np.median(ev.range_error):>+12.2f} mm"
        f"{1e3 * np.std(ev.range_error):>9.2f} mm"
        f"{math.degrees(np.median(ev.bearing_error)):>+13.4f} deg"
        f"{math.degrees(np.std(ev.bearing_error)):>10.4f} deg"
    )
    lines.append(
        f"detection + pose per 640x480 frame: median {np.median(ev.frame_ms):.1f} ms wall-clock "
        f"(CPU {np.median(ev.cpu_ms):.1f} ms), 90th percentile {np.percentile(ev.frame_ms, 90):.1f}"
        " ms"
    )
    lines.append(
        "targets: " + "; ".join(f"{k}: {'yes' if ok else 'NO'}" for k, ok in ev.targets().items())
    )
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# Replay from frames against replay from exact detections


@dataclass(frozen=True)
class ReplayComparison:
    """Map errors (eq. 17 mean distance, m) of one simulated run replayed four ways.

    frames : detections made from the run's camera frames.
    same_sightings : the same (time, tag) sightings with their exact range and bearing: what
        the frames would give with perfect vision.
    exact : the simulator's own detections of the run, without noise or dropout. It sees with
        the camera the frames were rendered with (`ekfslam.core.camera.tags_in_view`), so it has
        about the sightings the frames have.
    noisy : the simulator's noisy detections (2 cm, 0.02 rad, 10 % dropout).
    frames_detections, exact_detections : sightings (time, tag) of the frames and of the
    simulator's exact detections; common_detections : those in both.
    """

    name: str
    frames_error: float
    same_sightings_error: float
    exact_error: float
    noisy_error: float
    frames_detections: int
    exact_detections: int
    common_detections: int

    @property
    def ratio(self) -> float:
        """frames error / the simulator's exact detections' error: the issue's target."""
        return self.frames_error / self.exact_error

    @property
    def vision_ratio(self) -> float:
        """frames error / same-sightings exact error: what vision alone costs the map."""
        return self.frames_error / self.same_sightings_error


def exact_sightings(run: RunLog) -> Detections:
    """The run's detections with range and bearing replaced by their true values (ground truth)."""
    d = run.detections
    pose, _ = interpolate_poses(run.groundtruth, d.t)
    tags = np.array([run.meta.tag_map[int(i)] for i in d.tag_id]).reshape(-1, 2)
    delta = tags - pose[:, :2]
    bearing = wrap_angle(np.arctan2(delta[:, 1], delta[:, 0]) - pose[:, 2])
    return Detections(d.t, d.tag_id, np.hypot(delta[:, 0], delta[:, 1]), np.asarray(bearing))


def compare_replays(folder: str | Path, config: VisionConfig | None = None) -> ReplayComparison:
    """Replay a simulated run of camera frames from its frames and from exact detections.

    All four replays use the run's default noise (`ekfslam.core.noise.default_noise`).
    """
    meta = read_meta(Path(folder) / "run.json")
    sim = meta.simulation or {}
    if "config" not in sim:
        raise ValueError(f"{folder}: not a simulated run (no simulation config in run.json)")
    base = config_from_dict(sim["config"])
    seen = (base.camera, base.tags, tuple(base.camera_mounting))
    if seen != (meta.camera, meta.tags, tuple(meta.camera_mounting.tolist())):
        raise ValueError(
            f"{folder}: its frames were not rendered with the camera, tags and mounting its "
            "simulator saw with; render them again (`render-frames` without --mounting)"
        )
    run, _ = read_frames_run(folder, config)
    if run.groundtruth is None:
        raise ValueError(f"{folder}: a simulated run without its ground truth")
    exact = simulate(
        dataclasses.replace(base, range_noise_sigma=0.0, bearing_noise_sigma=0.0, dropout=0.0)
    )
    noisy = simulate(base)
    if not np.allclose(exact.groundtruth.pose, run.groundtruth.pose, atol=1e-9):
        raise ValueError(f"{folder}: the simulator no longer reproduces this run's ground truth")
    same = dataclasses.replace(run, detections=exact_sightings(run))
    noise = default_noise(run)
    errors = [
        summarize(r, replay(r, noise)).alignment.mean_error for r in (run, same, exact, noisy)
    ]
    pairs = [
        set(zip(d.t.tolist(), d.tag_id.tolist(), strict=True))
        for d in (run.detections, exact.detections)
    ]
    counts = (len(pairs[0]), len(pairs[1]), len(pairs[0] & pairs[1]))
    return ReplayComparison(run.meta.name, *errors, *counts)
