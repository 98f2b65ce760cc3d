"""Tests of the Q of each sighting (ekfslam.core.noise): a run's own σ, or σ_r growing with the
range."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ekfslam.core.noise import NoiseConfig, sighting_noise
from ekfslam.errors import ConfigError
from ekfslam.logs.runlog import Controls, Detections, RunLog, RunMeta


def _run(source: str, sigmas: bool = False) -> RunLog:
    t = np.arange(0.0, 20.0, 1.0)
    w = np.where(np.arange(len(t)) % 2 == 0, 0.0, 0.5)
    twist = np.column_stack([np.full(len(t), 0.1), np.zeros(len(t)), w])
    extra = (np.array([0.1, 0.2]), np.array([0.01, 0.05])) if sigmas else ()
    return RunLog(
        meta=RunMeta(name="r", source=source, nominal_start=np.zeros(3)),
        controls=Controls(t=t, kind="twist", values=twist),
        detections=Detections(
            np.array([1.0, 2.0]), np.array([1, 2]), np.array([1.0, 3.0]), np.zeros(2), *extra
        ),
    )


def test_each_sighting_gets_its_own_q_when_the_run_gives_its_sigmas() -> None:
    run = _run("recorded", sigmas=True)
    Q = sighting_noise(NoiseConfig(), run.detections)
    assert Q.shape == (2, 2, 2)
    np.testing.assert_allclose(Q[0], np.diag([0.1**2, 0.01**2]))
    np.testing.assert_allclose(Q[1], np.diag([0.2**2, 0.05**2]))
    ignored = sighting_noise(NoiseConfig(per_sighting=False), run.detections)
    np.testing.assert_array_equal(ignored, NoiseConfig().Q)  # (2, 2): one Q for all


def test_a_range_dependent_sigma_grows_with_each_sightings_range() -> None:
    run = _run("recorded")
    noise = NoiseConfig(sigma_range=0.02, sigma_range_per_m=0.01)
    Q = sighting_noise(noise, run.detections)
    assert Q[:, 0, 0] == pytest.approx([(0.02 + 0.01 * 1.0) ** 2, (0.02 + 0.01 * 3.0) ** 2])
    assert Q[:, 1, 1] == pytest.approx([0.03**2, 0.03**2])
    assert sighting_noise(NoiseConfig(), run.detections).shape == (2, 2)


def test_bad_per_sighting_settings_are_refused() -> None:
    with pytest.raises(ConfigError, match="sigma_range_per_m"):
        NoiseConfig(sigma_range_per_m=-0.1)
    with pytest.raises(ConfigError, match="per_sighting"):
        NoiseConfig(per_sighting="yes")
    assert dataclasses.replace(NoiseConfig(), sigma_range_per_m=0.0) == NoiseConfig()
