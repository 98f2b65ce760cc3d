"""The vision study: `evaluate_vision`'s table, and a run replayed from its frames against truth.

``python -m studies vision-eval`` prints `format_evaluation` of
`ekfslam.analysis.vision_eval.evaluate_vision` (detection rate, range and bearing errors by
distance band, time per frame, each beside the issue's targets) and, with ``--run RUN`` (a
simulated run of camera frames), the map error (eq. 17) of the run replayed from its frames
against the same run replayed from the simulator's exact detections (`compare_replays`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ekfslam.analysis.evaluation import interpolate_poses, summarize
from ekfslam.analysis.vision_eval import VisionEvaluation
from ekfslam.core.noise import default_noise
from ekfslam.geometry import wrap_angle
from ekfslam.logs.runjson import read_meta
from ekfslam.logs.runlog import Detections, RunLog
from ekfslam.pipeline import replay
from ekfslam.sim.simulation import config_from_dict, simulate
from ekfslam.vision.detect import VisionConfig
from ekfslam.vision.frames_run import read_frames_run


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
