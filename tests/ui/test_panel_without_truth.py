"""The tuning panel on runs without ground truth: the estimate after eq. (17), no true path.

A constructed case (the seed's square with its ground truth removed and a wrong nominal start)
and MRCLAM Dataset 4 (no Vicon for its robots; shared data).
"""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

from ekfslam.errors import InputError
from ekfslam.logs.runlog import read_run
from ekfslam.places import seed_runs_dir
from ekfslam.ui.tuning import Tuner, mrclam_runs


@pytest.fixture(scope="module")
def square():
    return read_run(seed_runs_dir() / "square-2laps")


def shown(tuner: Tuner) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v = tuner.view
    path = np.column_stack([v.path.get_xdata(), v.path.get_ydata()])
    start = np.column_stack([v.start.get_xdata(), v.start.get_ydata()])
    return path, start, np.asarray(v.tags.get_offsets())


def test_without_ground_truth_the_panel_draws_the_estimate_after_eq17(square) -> None:
    # The filter believes it starts 1 m and 0.3 rad away from where the robot stood: its map
    # is built in that wrong frame, and only eq. (17) puts it back.
    wrong = np.array([1.0, -0.8, 0.3])
    blind = replace(square, groundtruth=None, meta=replace(square.meta, nominal_start=wrong))
    tuner = Tuner({"blind": lambda: blind}, Figure())
    state = tuner.apply()
    a = state.summary.alignment
    assert state.summary.ate_rmse is None and "no ground truth" in state.summary.ate_note
    path, start, tags = shown(tuner)
    np.testing.assert_allclose(path, a.apply(state.result.history.pose[:, :2]))
    truth = square.groundtruth.pose[0, :2]
    assert np.hypot(*(start[0] - truth)) < 0.05  # the recovered start, where the robot stood
    assert np.hypot(*(start[0] - wrong[:2])) > 0.5
    true_tags = np.array([square.meta.tag_map[i] for i in sorted(state.result.landmarks)])
    assert np.mean(np.hypot(*(tags - true_tags).T)) == pytest.approx(a.mean_error, abs=1e-9)
    assert len(tuner.view.true_path.get_xdata()) == 0
    last = state.text.splitlines()[-1]
    assert last.startswith("no ground truth, no ATE")
    shown_start = [float(v) for v in re.findall(r"[-+]?\d+\.\d+", last)]
    np.testing.assert_allclose(shown_start, state.summary.start_pose, atol=6e-4)


def test_with_ground_truth_the_panel_draws_what_the_filter_made(square) -> None:
    tuner = Tuner({"square": lambda: square}, Figure())
    state = tuner.apply()
    path, start, _ = shown(tuner)
    np.testing.assert_array_equal(path, state.result.history.pose[:, :2])
    np.testing.assert_array_equal(start[0], square.groundtruth.pose[0, :2])
    assert len(state.text.splitlines()) == 3 and "ground truth" not in state.text


def test_mrclam_runs_names_each_robot_and_refuses_a_missing_dataset(tmp_path: Path) -> None:
    runs = mrclam_runs((tmp_path,), robots=(1, 3))
    assert list(runs) == [f"mrclam{tmp_path.name}-r1", f"mrclam{tmp_path.name}-r3"]
    with pytest.raises(InputError):
        runs[f"mrclam{tmp_path.name}-r1"]()  # an empty folder is no MRCLAM dataset


def test_a_dataset4_robot_in_the_panel(shared_data: Path, data_missing) -> None:
    folder = shared_data / "mrclam" / "MRCLAM_Dataset4"
    if not (folder / "Barcodes.dat").is_file():
        data_missing(f"MRCLAM Dataset 4 not in {folder.parent}")
    runs = mrclam_runs((folder,), robots=(2,))
    tuner = Tuner(runs, Figure())
    state = tuner.apply()
    assert state.settings.run == "mrclam4-r2"
    assert state.summary.ate_rmse is None and state.summary.ate_note
    assert state.summary.alignment.mean_error < 0.05  # 0.020 m with the shipped default
    row = state.text.splitlines()[1].split()
    assert float(row[4]) == pytest.approx(state.summary.alignment.mean_error, abs=6e-4)
    _, start, _ = shown(tuner)
    assert len(start) == 1 and len(tuner.view.true_path.get_xdata()) == 0
