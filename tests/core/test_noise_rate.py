"""Tests of the noise a run gets by default: the variance its odometry's rate adds, and the Q of
each sighting (ekfslam.core.noise)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ekfslam.core.noise import (
    NoiseConfig,
    default_noise,
    odometry_hold_density,
    sighting_noise,
    with_odometry_rate,
)
from ekfslam.errors import ConfigError
from ekfslam.logs.runlog import Controls, Detections, RunLog, RunMeta


def test_a_constant_speed_held_adds_nothing() -> None:
    t = np.arange(0.0, 10.0, 0.125)
    twist = np.tile([0.1, 0.0, 0.3], (len(t), 1))
    assert odometry_hold_density(t, twist).tolist() == [0.0, 0.0, 0.0]


def test_evenly_spaced_rows_add_the_square_of_each_change_times_the_interval_over_3() -> None:
    dt, jump = 0.5, 0.2
    t = np.arange(0.0, 100.0 + dt / 2, dt)
    w = np.where(np.arange(len(t)) % 2 == 0, 0.0, jump)  # ω changes by 0.2 rad/s at each row
    twist = np.column_stack([np.zeros(len(t)), np.zeros(len(t)), w])
    density = odometry_hold_density(t, twist)
    assert density[2] == pytest.approx(jump**2 * dt / 3, rel=1e-12)  # rad²/s
    assert density[:2].tolist() == [0.0, 0.0]


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**31 - 1), st.sampled_from([2, 4, 8]))
def test_a_smooth_speed_held_longer_adds_more(seed, k) -> None:
    """A speed that varies smoothly, logged at 100 Hz and at 100/k Hz (each k-th row held): the
    sparser log adds about k times more (J grows k times, Δ k times, per second J² Δ / 3 k)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 200.0, 0.01)
    w = np.cumsum(rng.standard_normal(len(t))) * 0.01  # a random walk
    twist = np.column_stack([np.zeros_like(t), np.zeros_like(t), w])
    dense = odometry_hold_density(t, twist)[2]
    sparse = odometry_hold_density(t[::k], twist[::k])[2]
    assert sparse == pytest.approx(k * k * dense, rel=0.35)


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


def test_a_recorded_run_gets_the_variance_of_its_rate_a_simulated_one_none() -> None:
    assert default_noise(_run("simulated")) == NoiseConfig()
    recorded = default_noise(_run("recorded"))
    extra = odometry_hold_density(*(lambda r: (r.controls.t, r.control_twist()))(_run("recorded")))
    assert recorded.sigma_theta == pytest.approx(
        math.sqrt(NoiseConfig().sigma_theta ** 2 + extra[2])
    )
    assert recorded.sigma_x == NoiseConfig().sigma_x  # the forward speed never changes
    assert (recorded.sigma_range, recorded.sigma_bearing) == (0.03, 0.03)


def test_a_fixed_per_step_r_is_left_as_it_is() -> None:
    fixed = NoiseConfig(R_per_step=((1e-4, 0, 0), (0, 1e-4, 0), (0, 0, 1e-4)))
    run = _run("recorded")
    assert with_odometry_rate(fixed, run.controls.t, run.control_twist()) is fixed


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
