"""MRCLAM Datasets 1 and 4 (no Robot*_Groundtruth.dat): the replay, and Dataset 1's barcode swap.

Shared-data tests: skipped (a failure in CI) without ../shared/data/mrclam/MRCLAM_Dataset1.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from ekfslam.analysis.evaluation import NO_GROUNDTRUTH, summarize
from ekfslam.cli.main import main
from ekfslam.logs.mrclam.defaults import MRCLAM_CONFIG, MRCLAM_NOISE
from ekfslam.logs.mrclam.load import load_mrclam
from ekfslam.pipeline import replay

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def dataset1(shared_data: Path, data_missing) -> Path:
    folder = shared_data / "mrclam" / "MRCLAM_Dataset1"
    if not (folder / "Barcodes.dat").is_file():
        data_missing(f"MRCLAM Dataset 1 not in {folder.parent}")
    return folder


def aligned_error(folder: Path, robot: int, **load) -> float:
    run, _ = load_mrclam(folder, robot, **load)
    return summarize(run, replay(run, MRCLAM_NOISE, MRCLAM_CONFIG)).alignment.mean_error


def test_the_barcode_swap_of_dataset_1_is_real(dataset1: Path) -> None:
    """Scored both ways, the swapped-back barcodes fit the true map twenty times better."""
    published = aligned_error(dataset1, 2, fix_barcode_swap=False)
    fixed = aligned_error(dataset1, 2)
    assert published > 0.5 and fixed < 0.05  # measured 0.84 m and 0.031 m
    _, report = load_mrclam(dataset1, 2)
    assert report.barcode_swap_fixed and report.barcode_swap_renamed == 946
    swap = report.as_dict()["loaded"]["barcode_swap"]
    assert swap["fixed"] and swap["sightings_renamed"] == 946 and "11 and 17" in swap["reason"]


def test_run_without_groundtruth_json(dataset1: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["run", str(dataset1), "--robot", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["trajectory"] == {"ate_rmse": None, "reason": NO_GROUNDTRUTH}
    assert out["true_start"] is None and out["loaded"]["groundtruth_rows"] == 0
    a = out["alignment"]
    assert a["start_pose"] == [a["x0"], a["y0"], a["theta0"]]  # started at the origin
    assert a["landmarks_matched"] == 15 and a["mean_error"] < 0.05
    assert out["loaded"]["time_offsets"] == {"start_s": 1.585, "end_s": 1.5}


def test_run_without_groundtruth_text_and_start(
    dataset1: Path, capsys: pytest.CaptureFixture
) -> None:
    assert main(["run", str(dataset1), "--robot", "2", "--start", "1", "2", "0.5"]) == 0
    text = capsys.readouterr().out
    assert "trajectory ATE RMSE: none, the run has no ground truth" in text
    assert "no ground truth (no Robot*_Groundtruth.dat)" in text
    assert "true start pose" not in text and "recovered start pose: (" in text


def test_our_run_format_without_groundtruth_follows_the_same_rule(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """One rule for both formats: a run folder without groundtruth.csv scores its map only."""
    run = tmp_path / "square"
    shutil.copytree(REPO / "data" / "runs" / "square-2laps", run)
    (run / "groundtruth.csv").unlink()
    assert main(["run", str(run), "--json", "--start", "0.1", "0", "0"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["trajectory"] == {"ate_rmse": None, "reason": NO_GROUNDTRUTH}
    assert out["true_start"] is None and out["alignment"]["landmarks_matched"] == 8
    assert main(["run", str(run), "--max-range", "6"]) == 2  # MRCLAM only
    assert "--max-range is only for MRCLAM" in capsys.readouterr().err


def test_convert_and_tum_without_groundtruth(
    dataset1: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "robot4"
    assert main(["convert", "mrclam", str(dataset1), "--robot", "4", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "no ground truth" in text and "489 sightings renamed" in text
    assert sorted(p.name for p in out.iterdir()) == ["controls.csv", "detections.csv", "run.json"]
    assert main(["tum", str(out), "--out", str(tmp_path / "tum")]) == 0
    written = sorted(p.name for p in (tmp_path / "tum").iterdir())
    assert written == ["map.tum", "map_truth.tum", "trajectory.tum"]  # no groundtruth.tum
