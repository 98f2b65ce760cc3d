"""Runs logged as camera frames: run.json's camera keys, frames on disk, detection, replay."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from ekfslam.analysis.evaluation import interpolate_poses
from ekfslam.cli.main import main
from ekfslam.core.camera import Camera, TagSpec, pinhole_camera
from ekfslam.errors import InputError
from ekfslam.geometry import wrap_angle
from ekfslam.logs.frames import (
    FRAMES_CSV,
    frame_times,
    has_frames_only,
    iter_frames,
    read_frame_index,
)
from ekfslam.logs.runjson import FramesSpec, meta_json, read_meta
from ekfslam.logs.runlog import Controls, Detections, GroundTruth, RunLog, read_run, write_run
from ekfslam.sim.simulation import SimulationConfig, simulate
from ekfslam.vision.detect import TagObserver, observations_table
from ekfslam.vision.frames_run import read_frames_run, with_camera, write_frames_run
from ekfslam.vision.render import ArenaRenderer, RenderConfig

REPO = Path(__file__).resolve().parents[2]
DATA_RUN = REPO / "data" / "runs" / "square-1lap-frames"


@pytest.fixture(scope="module")
def short_run() -> RunLog:
    """The first 1.5 s of a simulated square run (16 camera frames), camera 6 cm ahead."""
    run = simulate(SimulationConfig(trajectory="square", laps=1, seed=3))
    keep = run.controls.t <= 1.5
    gt = run.groundtruth
    run = dataclasses.replace(
        run,
        controls=Controls(run.controls.t[keep], "wheels", run.controls.values[keep]),
        groundtruth=GroundTruth(gt.t[keep], gt.pose[keep]),
    )
    return with_camera(run, mounting=(0.06, 0.0, 0.0), name="short-frames")


@pytest.fixture(scope="module")
def video_run(short_run: RunLog, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("runs") / "video"
    write_frames_run(short_run, folder)
    return folder


def _errors(run: RunLog) -> tuple[np.ndarray, np.ndarray]:
    d = run.detections
    pose, inside = interpolate_poses(run.groundtruth, d.t)
    assert inside.all()
    tags = np.array([run.meta.tag_map[int(i)] for i in d.tag_id])
    delta = tags - pose[:, :2]
    true_range = np.hypot(delta[:, 0], delta[:, 1])
    true_bearing = np.arctan2(delta[:, 1], delta[:, 0]) - pose[:, 2]
    return d.range - true_range, wrap_angle(d.bearing - true_bearing)


# ---------------------------------------------------------------------------------------------
# run.json


def test_camera_tags_and_frames_round_trip_through_run_json(tmp_path: Path, short_run) -> None:
    camera = Camera(
        800,
        600,
        610.5,
        611.25,
        401.0,
        297.5,
        (-0.1, 0.02, 0.001, -0.002, 0.005),
        mount_height=0.2,
        pitch=0.05,
    )
    meta = dataclasses.replace(
        short_run.meta, camera=camera, tags=TagSpec(0.1), frames=FramesSpec("images", "f/%04d.png")
    )
    run = dataclasses.replace(short_run, meta=meta)
    write_run(run, tmp_path / "r")
    back = read_run(tmp_path / "r")
    assert back.meta.camera == camera and back.meta.tags == TagSpec(0.1)
    assert back.meta.frames == FramesSpec("images", "f/%04d.png")
    assert back.meta.frames.path(7) == "f/0007.png"


def test_only_a_run_with_frames_may_leave_detections_out(tmp_path: Path, short_run) -> None:
    plain = dataclasses.replace(short_run, meta=dataclasses.replace(short_run.meta, frames=None))
    with pytest.raises(InputError, match="needs frames"):
        write_run(plain, tmp_path / "a", with_detections=False)
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "detections.csv").write_text("t,tag_id,range,bearing\n")  # stale
    write_run(short_run, tmp_path / "b", overwrite=True, with_detections=False)
    assert not (tmp_path / "b" / "detections.csv").exists()
    no_camera = dataclasses.replace(short_run.meta, camera=None)
    with pytest.raises(InputError, match='needs "camera"'):
        write_run(dataclasses.replace(short_run, meta=no_camera), tmp_path / "c")


def test_runs_without_a_camera_keep_their_exact_run_json() -> None:
    run = simulate(SimulationConfig(trajectory="square", laps=1, seed=1))
    doc = json.loads(meta_json(run.meta))
    # the simulator's config records the camera it saw with; run.json's top level has none
    assert not {"camera", "frames", "tags"} & set(doc)
    assert doc["simulation"]["config"]["camera"]["width"] == 640


def test_a_simulated_run_is_framed_with_the_camera_its_simulator_saw_with() -> None:
    camera = pinhole_camera(horizontal_fov_deg=80.0, mount_height=0.2)
    config = SimulationConfig(
        laps=1, seed=2, camera=camera, tag_size=0.1, camera_mounting=(0.03, 0.0, 0.0)
    )
    framed = with_camera(simulate(config))
    assert framed.meta.camera == camera and framed.meta.tags == TagSpec(0.1)
    assert framed.meta.camera_mounting.tolist() == [0.03, 0.0, 0.0]
    other = pinhole_camera(width=320, height=240)
    assert with_camera(simulate(config), camera=other).meta.camera == other


def _write_doc(folder: Path, **changes) -> Path:
    folder.mkdir()
    doc = {
        "format": "ekfslam-run",
        "format_version": 1,
        "name": "x",
        "source": "recorded",
        "units": {"length": "m", "angle": "rad", "time": "s"},
        "camera_mounting": {"x": 0.0, "y": 0.0, "yaw": 0.0},
        "nominal_start": [0.0, 0.0, 0.0],
        "camera": {"image_size": [640, 480], "fx": 500.0, "fy": 500.0, "cx": 319.5, "cy": 239.5},
        "tags": {"family": "tag36h11", "size": 0.16},
        "frames": {"kind": "video", "file": "frames.mp4"},
    } | changes
    (folder / "run.json").write_text(json.dumps({k: v for k, v in doc.items() if v is not None}))
    (folder / "controls.csv").write_text("t,vx,vy,wz\n0.0,0.0,0.0,0.0\n")
    return folder


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"camera": None}, 'needs "camera"'),
        ({"camera": {"image_size": [640.5, 480], "fx": 1, "fy": 1, "cx": 0, "cy": 0}}, "whole"),
        ({"camera": {"image_size": [640, 480], "fx": 1, "fy": 1, "cx": 0}}, "missing cy"),
        ({"camera": {"image_size": [64, 48], "fx": -1, "fy": 1, "cx": 0, "cy": 0}}, "fx"),
        (
            {
                "camera": {
                    "image_size": [64, 48],
                    "fx": 1,
                    "fy": 1,
                    "cx": 0,
                    "cy": 0,
                    "distortion": [0.1],
                }
            },
            "k1, k2, p1, p2",
        ),
        ({"tags": {"family": "tag25h9", "size": 0.16}}, 'only "tag36h11"'),
        ({"tags": {"family": "tag36h11", "size": 0}}, "size"),
        ({"frames": {"kind": "movie", "file": "a.mp4"}}, "video"),
        ({"frames": {"kind": "video", "file": "../elsewhere.mp4"}}, "inside the run folder"),
        ({"frames": {"kind": "images", "file": "frames/img.png"}}, "integer field"),
    ],
)
def test_bad_camera_keys_are_named(tmp_path: Path, changes: dict, message: str) -> None:
    folder = _write_doc(tmp_path / "run", **changes)
    with pytest.raises(InputError, match=message):
        read_run(folder)


def test_a_frames_run_without_detections_says_how_to_make_them(tmp_path: Path) -> None:
    folder = _write_doc(tmp_path / "run")
    with pytest.raises(InputError, match="ekfslam detect"):
        read_run(folder)
    assert has_frames_only(folder)
    (folder / "run.json").write_text(
        (folder / "run.json")
        .read_text()
        .replace(', "frames": {"kind": "video", "file": "frames.mp4"}', "")
    )
    with pytest.raises(InputError, match="a run folder holds"):
        read_run(folder)


# ---------------------------------------------------------------------------------------------
# Frames on disk


def test_frames_csv_errors_name_the_line(tmp_path: Path) -> None:
    (tmp_path / FRAMES_CSV).write_text("t,frame\n0.0,0\n0.1,1\n0.2,1\n")
    with pytest.raises(InputError, match=r"frames.csv:4: frame 1 does not increase"):
        read_frame_index(tmp_path)
    (tmp_path / FRAMES_CSV).write_text("t,frame\n0.0,0\n0.1,1.5\n")
    with pytest.raises(InputError, match=r"frames.csv:3: frame is not an integer"):
        read_frame_index(tmp_path)
    (tmp_path / FRAMES_CSV).write_text("t,frame\n0.2,0\n0.1,1\n")
    with pytest.raises(InputError, match=r"frames.csv:3: time 0.1 s is before"):
        read_frame_index(tmp_path)


def test_frame_times_are_the_ground_truth_at_camera_times() -> None:
    t = np.arange(0, 21) * 0.05
    pose = np.column_stack([t, -t, wrap_angle(3.0 + 2.0 * t)])  # wraps through ±π
    ft = frame_times(t, pose, 10.0)
    assert ft.t == pytest.approx(np.arange(11) * 0.1)
    assert ft.pose == pytest.approx(pose[::2], abs=1e-12)


def test_video_frames_are_the_rendered_frames_to_within_compression(video_run, short_run) -> None:
    meta = read_run(video_run, detections=short_run.detections).meta
    index = read_frame_index(video_run)
    assert index.frame.tolist() == list(range(16)) and index.t[-1] == pytest.approx(1.5)
    frames = list(iter_frames(video_run, meta, index))
    renderer = ArenaRenderer(meta.camera, meta.tags, meta.camera_mounting)
    ft = frame_times(short_run.groundtruth.t, short_run.groundtruth.pose, 10.0)
    original = renderer.render(ft.pose[5], 5)
    assert frames[5].shape == (480, 640)
    assert np.abs(frames[5].astype(float) - original).mean() < 4.0  # mp4v is lossy
    assert not np.array_equal(frames[5], frames[6])


def test_image_frames_are_exact(tmp_path: Path, short_run) -> None:
    keep = short_run.controls.t <= 0.3  # four frames
    gt = short_run.groundtruth
    run = dataclasses.replace(
        with_camera(short_run, mounting=(0.06, 0.0, 0.0), kind="images"),
        controls=Controls(short_run.controls.t[keep], "wheels", short_run.controls.values[keep]),
        groundtruth=GroundTruth(gt.t[keep], gt.pose[keep]),
    )
    index = write_frames_run(run, tmp_path / "img", render=RenderConfig(seed=4))
    assert (tmp_path / "img" / "frames" / "000003.png").is_file()
    assert not (tmp_path / "img" / "frames" / "000004.png").exists()
    frames = list(iter_frames(tmp_path / "img", run.meta, index))
    renderer = ArenaRenderer(
        run.meta.camera, run.meta.tags, (0.06, 0.0, 0.0), config=RenderConfig(seed=4)
    )
    ft = frame_times(short_run.groundtruth.t, short_run.groundtruth.pose, 10.0)
    assert np.array_equal(frames[3], renderer.render(ft.pose[3], 3))


def test_a_video_shorter_than_frames_csv_is_an_error(video_run, tmp_path: Path) -> None:
    meta = read_meta(video_run / "run.json")
    index = dataclasses.replace(read_frame_index(video_run), frame=np.array([0, 3, 40]))
    with pytest.raises(InputError, match="ends after 16 frames"):
        list(iter_frames(video_run, meta, index))


# ---------------------------------------------------------------------------------------------
# Detect and replay


def test_detections_from_frames_match_the_truth(video_run) -> None:
    run, report = read_frames_run(video_run)
    assert len(run.detections.t) >= 16  # tags 1 and 2 are ahead at the start of the square
    range_error, bearing_error = _errors(run)
    assert abs(np.median(range_error)) < 0.002 and np.std(range_error) < 0.005
    assert np.std(bearing_error) < math.radians(0.05)
    d = report.as_dict()
    assert set(d) == {"loaded", "dropped"}
    assert d["loaded"]["detections"] == len(run.detections.t)
    assert set(d["dropped"]) == {
        "nonfinite",
        "unknown_id",
        "duplicate_id",
        "outside_frame",
        "edge_on",
    }
    assert all(set(v) == {"count", "reason"} for v in d["dropped"].values())


def test_detect_command_then_run_command(video_run, tmp_path: Path, capsys) -> None:
    # run straight from the frames (no detections.csv) ...
    assert main(["run", str(video_run), "--json"]) == 0
    direct = json.loads(capsys.readouterr().out)
    assert direct["dropped"]["nonfinite"]["count"] == 0
    assert direct["detections"] == "frames (detected now)"
    assert direct["loaded"]["frames"] == 16
    # ... then detect once, and the same replay reads detections.csv
    out = tmp_path / "det.csv"
    assert main(["detect", str(video_run), "--out", str(out)]) == 0
    assert "detections from 16 frames" in capsys.readouterr().out
    assert main(["detect", str(video_run), "--out", str(out)]) == 2  # refuses to overwrite
    assert "exists" in capsys.readouterr().err
    folder = tmp_path / "copy"
    folder.mkdir()
    for f in video_run.iterdir():
        (folder / f.name).write_bytes(f.read_bytes())
    (folder / "detections.csv").write_bytes(out.read_bytes())
    assert not has_frames_only(folder)
    assert main(["run", str(folder), "--json"]) == 0
    from_csv = json.loads(capsys.readouterr().out)
    assert from_csv["landmarks"] == direct["landmarks"]
    assert from_csv["alignment"] == direct["alignment"]
    assert from_csv["detections"].startswith("detections.csv (not the run's frames;")


def test_detect_writes_into_the_run_only_when_asked(video_run, tmp_path: Path, capsys) -> None:
    """Regression: `detect RUN` wrote RUN/detections.csv and `run` then silently used it."""
    before = sorted(p.name for p in video_run.iterdir())
    assert main(["detect", str(video_run)]) == 2
    err = capsys.readouterr().err
    assert "--out DIR" in err and "--in-place" in err and len(err.strip().splitlines()) == 1
    both = ["detect", str(video_run), "--out", str(tmp_path / "x"), "--in-place"]
    assert main(both) == 2 and "not both" in capsys.readouterr().err
    assert main(["detect", str(video_run), "--out", str(video_run / "sub")]) == 2
    assert "inside the run" in capsys.readouterr().err
    assert sorted(p.name for p in video_run.iterdir()) == before  # nothing written
    # --out DIR: a new run folder, the original untouched and still replayed from its frames
    copy = tmp_path / "detected"
    assert main(["detect", str(video_run), "--out", str(copy)]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {copy / 'detections.csv'}: ")
    assert sorted(p.name for p in copy.iterdir()) == sorted([*before, "detections.csv"])
    assert sorted(p.name for p in video_run.iterdir()) == before
    assert main(["detect", str(video_run), "--out", str(copy)]) == 2  # not over a run
    assert "not empty; pass --overwrite" in capsys.readouterr().err
    assert main(["run", str(copy)]) == 0
    text = capsys.readouterr().out.splitlines()
    assert (
        "detections: detections.csv (not the run's frames; delete it to detect from them)" in text
    )
    assert main(["run", str(video_run)]) == 0
    text = capsys.readouterr().out.splitlines()
    assert "detections: frames (detected now)" in text
    assert "loaded: 16 frames, " in "\n".join(text)
    assert any(line.startswith("dropped: ") for line in text)
    # --in-place, asked for
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    for f in video_run.iterdir():
        (scratch / f.name).write_bytes(f.read_bytes())
    assert main(["detect", str(scratch), "--in-place"]) == 0
    assert (scratch / "detections.csv").read_bytes() == (copy / "detections.csv").read_bytes()


def test_the_shipped_frames_run_reads_and_detects() -> None:
    if not DATA_RUN.is_dir():
        pytest.fail(f"{DATA_RUN} is missing; make it as data/README.md says")
    assert not (DATA_RUN / "detections.csv").exists()  # a run logged as frames only
    assert sum(f.stat().st_size for f in DATA_RUN.iterdir()) < 5e6
    meta = read_meta(DATA_RUN / "run.json")
    assert meta.frames == FramesSpec("video", "frames.mp4") and meta.tags == TagSpec(0.16)
    index = read_frame_index(DATA_RUN)
    assert 250 <= len(index.t) <= 350  # about 30 s at 10 Hz
    # the first 30 frames (3 s), detected and compared with the ground truth
    first = dataclasses.replace(index, t=index.t[:30], frame=index.frame[:30])
    observer = TagObserver(meta.camera, meta.tags, meta.camera_mounting, meta.tag_map.keys())
    results = [observer.observe(image) for image in iter_frames(DATA_RUN, meta, first)]
    t, ids, rng, bearing = observations_table(first.t.tolist(), results)
    run = read_run(DATA_RUN, detections=Detections(t, ids, rng, bearing))
    assert len(t) >= 30
    range_error, bearing_error = _errors(run)
    assert abs(np.median(range_error)) < 0.002 and np.std(range_error) < 0.005
    assert np.std(bearing_error) < math.radians(0.05)
