"""Tests of ekfslam.analysis.rescue: the innovations' likelihood picks R for a log the documented
noise does not fit, and leaves a log it fits alone."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ekfslam.analysis.evaluation import summarize
from ekfslam.analysis.rescue import (
    RESCUE_SCALES,
    log_likelihood,
    replay_rescued,
    scaled_motion,
)
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.noise import NoiseConfig
from ekfslam.logs.runlog import Controls, RunLog, read_run
from ekfslam.pipeline import replay

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


def held(run: RunLog, seconds: float) -> RunLog:
    """The run with its wheel speeds held `seconds` at a time (a coarser odometry log)."""
    c = run.controls
    piece = np.floor((c.t - c.t[0]) / seconds)
    first = np.concatenate([[True], piece[1:] != piece[:-1]])
    return dataclasses.replace(run, controls=Controls(c.t[first], c.kind, c.values[first]))


@pytest.fixture(scope="module")
def square() -> RunLog:
    return read_run(RUNS / "square-2laps")


def test_a_replay_that_is_ok_is_not_touched(square) -> None:
    rescue = replay_rescued(square, NoiseConfig(), FilterConfig())
    assert (rescue.scale, rescue.rescued, len(rescue.tried)) == (1.0, False, 1)
    np.testing.assert_array_equal(rescue.result.mu, replay(square).mu)
    assert rescue.line() is None
    assert rescue.as_dict()["tried"][0]["verdict"] == "ok"


def test_a_log_held_half_a_second_is_rescued_by_the_most_likely_r(square) -> None:
    """The square with its odometry held 0.5 s at a time: the documented noise is lost; R x 4
    is the most likely of x 1-16 and maps the square as the full log does (0.013 m)."""
    coarse = held(square, 0.5)
    rescue = replay_rescued(coarse, NoiseConfig(), FilterConfig())
    assert rescue.documented.verdict == "lost"
    assert [what for what, _, _ in rescue.tried] == ["x1", *(f"x{f:g}" for f in RESCUE_SCALES)]
    likelihoods = [ll for _, ll, _ in rescue.tried]
    assert rescue.tried[int(np.argmax(likelihoods))][0] == "x4" and rescue.scale == 4.0
    assert not rescue.reinitialise
    assert rescue.result.noise == scaled_motion(NoiseConfig(), 4.0)
    assert rescue.result.diagnosis.verdict == "ok"
    assert summarize(coarse, rescue.result).alignment.mean_error < 0.02
    assert log_likelihood(rescue.result) == pytest.approx(max(likelihoods))
    assert rescue.line().startswith("noise: the documented noise was lost (")
    assert rescue.line().endswith(
        "replayed with R x 4, the most likely of x1 lost, x2 ok, x4 ok, x8 ok, x16 ok"
    )


def test_scaling_the_motion_noise_scales_sigma_x_y_theta_and_nothing_else() -> None:
    noise = NoiseConfig(sigma_x=0.01, sigma_y=0.02, sigma_theta=0.03, sigma_range=0.4)
    scaled = scaled_motion(noise, 4.0)
    assert (scaled.sigma_x, scaled.sigma_y, scaled.sigma_theta) == (0.04, 0.08, 0.12)
    assert (scaled.sigma_range, scaled.sigma_bearing) == (0.4, noise.sigma_bearing)
