"""The simulated team: each run is `simulate`'s, and the robots' sightings of one another are the
true geometry plus the configured noise (a χ² band on the normalised residuals)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy import stats

from ekfslam.core.arena import SEED_ARENA
from ekfslam.geometry import wrap_angle
from ekfslam.logs.team import check_team
from ekfslam.sim.config import SimulationConfig
from ekfslam.sim.simulation import simulate
from ekfslam.sim.team import simulate_team

CONFIG = SimulationConfig(laps=1, seed=3, range_noise_sigma=0.03, bearing_noise_sigma=0.02)


@pytest.fixture(scope="module")
def team():
    return simulate_team((0.5, 0.75, 1.0, 1.25), CONFIG)


def _true(team, robot, t):
    gt = team.runs[robot].groundtruth
    heading = np.unwrap(gt.pose[:, 2])
    return np.column_stack(
        [
            np.interp(t, gt.t, gt.pose[:, 0]),
            np.interp(t, gt.t, gt.pose[:, 1]),
            np.interp(t, gt.t, heading),
        ]
    )


def test_each_run_is_the_simulators(team):
    check_team(team)
    for k, size in enumerate((0.5, 0.75, 1.0, 1.25), start=1):
        start = np.array([-size / 2, -size / 2, 0.0])
        alone = simulate(
            dataclasses.replace(CONFIG, size=size, seed=CONFIG.seed * 10 + k),
            dataclasses.replace(SEED_ARENA, nominal_start=start),
        )
        run = team.runs[k]
        assert np.array_equal(run.controls.values, alone.controls.values)
        assert np.array_equal(run.detections.range, alone.detections.range)
        assert np.array_equal(run.meta.nominal_start, start)


def test_sightings_are_the_truth_plus_the_configured_noise(team):
    s = team.sightings
    assert len(s) > 200 and len(s.pairs()) >= 6
    nu_r, nu_b = np.empty(len(s)), np.empty(len(s))
    for a in team.robots:
        for b in team.robots:
            k = np.flatnonzero((s.observer == a) & (s.target == b))
            if not k.size:
                continue
            pa, pb = _true(team, a, s.t[k]), _true(team, b, s.t[k])
            d = pb[:, :2] - pa[:, :2]
            r = np.hypot(d[:, 0], d[:, 1])
            bearing = np.arctan2(d[:, 1], d[:, 0]) - pa[:, 2]
            assert np.all(r >= CONFIG.camera_min_range - 1e-3)
            assert np.all(r <= CONFIG.camera_max_range + 1e-3)
            half_fov = CONFIG.camera.horizontal_fov / 2
            assert np.all(np.abs(wrap_angle(bearing)) <= half_fov + 1e-3)
            nu_r[k] = (s.range[k] - r) / CONFIG.range_noise_sigma
            nu_b[k] = wrap_angle(s.bearing[k] - bearing) / CONFIG.bearing_noise_sigma
    n = len(s)
    for nu in (nu_r, nu_b):  # each N(0, 1): mean and sum of squares inside 99.9% bands
        assert abs(nu.mean()) < stats.norm.ppf(0.9995) / math.sqrt(n)
        chi2 = float(nu @ nu)
        assert stats.chi2.ppf(0.0005, n) < chi2 < stats.chi2.ppf(0.9995, n)


def test_the_team_is_reproducible_and_bounded():
    one, two = simulate_team((0.5, 1.0), CONFIG), simulate_team((0.5, 1.0), CONFIG)
    assert np.array_equal(one.sightings.range, two.sightings.range)
    other = simulate_team((0.5, 1.0), dataclasses.replace(CONFIG, seed=4))
    assert not np.array_equal(one.runs[1].groundtruth.pose, other.runs[1].groundtruth.pose)
    with pytest.raises(ValueError, match="1 to 5 robots"):
        simulate_team((0.5,) * 6, CONFIG)
