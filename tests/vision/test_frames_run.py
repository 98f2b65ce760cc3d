"""vision.frames_run reads the simulator's camera from run.json as the simulator itself does."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from ekfslam.core.camera import pinhole_camera
from ekfslam.logs.runjson import RunMeta
from ekfslam.sim.simulation import SimulationConfig, config_from_dict
from ekfslam.vision.frames_run import simulated_view


def _meta(config: dict | None) -> RunMeta:
    simulation = None if config is None else {"config": config}
    return RunMeta("x", "simulated", np.zeros(3), simulation=simulation)


@pytest.mark.parametrize(
    "config",
    [
        SimulationConfig(),
        SimulationConfig(
            camera=pinhole_camera(width=320, height=240, horizontal_fov_deg=80.0), tag_size=0.1
        ),
    ],
)
def test_the_camera_a_simulated_run_saw_with_is_the_simulators(config: SimulationConfig) -> None:
    recorded = config.to_dict()
    seen = config_from_dict(recorded)
    assert simulated_view(_meta(recorded)) == (seen.camera, seen.tags)


def test_a_config_from_before_the_camera_model_gives_the_simulators_camera() -> None:
    legacy = {k: v for k, v in SimulationConfig().to_dict().items() if k != "camera"}
    for old in (legacy | {"camera_fov": math.radians(80.0)}, legacy):
        seen = config_from_dict(old)
        assert simulated_view(_meta(old)) == (seen.camera, seen.tags)


def test_a_run_without_a_simulator_config_has_no_simulated_view() -> None:
    assert simulated_view(_meta(None)) is None
    assert simulated_view(dataclasses.replace(_meta(None), simulation={"seed": 1})) is None
