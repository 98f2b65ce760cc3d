"""The MRCLAM loader's checks (`ekfslam.logs.mrclam.checks`): the barcode swap, the range cut."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ekfslam.logs.mrclam.checks import (
    DEFAULT_MAX_RANGE,
    beyond_range,
    fix_barcodes,
    time_offsets,
)
from ekfslam.logs.mrclam.load import load_mrclam

PUBLISHED_1 = {5: 1, 18: 11, 61: 17, 45: 18}  # part of Dataset 1's Barcodes.dat, as published


def test_dataset_1_swap_is_undone_once() -> None:
    fixed, done = fix_barcodes("1", PUBLISHED_1)
    assert done and fixed == {5: 1, 18: 17, 61: 11, 45: 18}
    again, done_again = fix_barcodes("1", fixed)  # a corrected copy is left alone
    assert not done_again and again == fixed


def test_other_datasets_keep_their_barcodes() -> None:
    mapping = {27: 11, 16: 17}  # Dataset 7's
    assert fix_barcodes("7", mapping) == (mapping, False)
    assert fix_barcodes("4", PUBLISHED_1) == (PUBLISHED_1, False)


def test_range_cut_and_offsets() -> None:
    ranges = np.array([0.5, 5.99, 6.0, 6.01, 9.0])
    assert beyond_range(ranges, 6.0).tolist() == [False, False, False, True, True]
    assert not beyond_range(ranges, None).any() and DEFAULT_MAX_RANGE is None
    offsets = time_offsets(np.array([10.0, 11.0, 20.0]), np.array([12.5, 19.25]))
    assert offsets == {"start_s": 2.5, "end_s": 0.75}


def test_range_cut_is_counted(mrclam7: Path) -> None:
    all_kept, everything = load_mrclam(mrclam7, 2)
    cut, report = load_mrclam(mrclam7, 2, max_range=6.0)
    assert everything.beyond_range_dropped == 0 and everything.max_range is None
    far = report.beyond_range_dropped
    assert far == 376  # Dataset 7, robot 2: sightings of landmarks beyond 6 m
    assert len(all_kept.detections.t) - len(cut.detections.t) == far
    assert float(cut.detections.range.max()) <= 6.0 < float(all_kept.detections.range.max())
    assert report.measurement_rows == (
        report.measurements_kept
        + report.robot_sightings_dropped
        + report.unknown_barcodes_dropped
        + far
    )
    dropped = report.as_dict()["dropped"]["beyond_range"]
    assert dropped["count"] == far and dropped["max_range_m"] == 6.0
    assert f"{far} beyond range (range over 6 m" in report.lines()[1]
