"""The in-sample noise grid on MRCLAM: ranked by the robots' average, each robot scored alike."""

from __future__ import annotations

from pathlib import Path

from ekfslam.analysis.mrclam_tuning import score_robots
from ekfslam.core.noise import NoiseConfig
from studies.mrclam_tuning import tune_noise


def test_tuning_sorts_by_the_average_and_scores_each_robot_alike(mrclam7: Path) -> None:
    grid = {"sigma_theta": (0.05, 0.5)}
    rows = tune_noise(mrclam7, grid, robots=(4,))
    assert [len(r.errors) for r in rows] == [1, 1]
    assert rows[0].mean <= rows[1].mean
    for row in rows:
        noise = NoiseConfig(sigma_y=0.005, sigma_theta=row.noise["sigma_theta"])
        assert row.errors[0] == score_robots(mrclam7, noise, robots=(4,))[0].aligned_error
