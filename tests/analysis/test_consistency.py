"""NEES/NIS consistency: chi-square bands, matched noise, the runner, the loop, the command line."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from ekfslam_cli import run_ekfslam

from ekfslam import FilterConfig, replay, simulate, write_run
from ekfslam.analysis.consistency import (
    chi2_band,
    compare,
    monte_carlo,
    run_errors,
)
from ekfslam.analysis.evaluation import interpolate_poses
from ekfslam.core.invariant import from_cartesian, pose_error
from ekfslam.core.noise import default_noise
from ekfslam.geometry import wrap_angle
from ekfslam.sim.scenarios import noise_for_simulation, ring_arena, scenario
from ekfslam.viz.consistency import plot_consistency

REPO = Path(__file__).resolve().parents[2]


cli = run_ekfslam


# ------------------------------------------------------------------------------ chi-square bands
def test_band_matches_bar_shalom_and_covers_95_percent_of_averages():
    # Bar-Shalom, Li & Kirubarajan (2001), sec. 5.4: 50 runs of a 2-dof NEES -> [1.5, 2.6]
    lo, hi = chi2_band(2, 50)
    assert (round(float(lo), 1), round(float(hi), 1)) == (1.5, 2.6)
    lo1, hi1 = chi2_band(3, 1)  # one run, 3 dof: the textbook quantiles 0.216 and 9.348
    assert float(lo1) == pytest.approx(0.2158, abs=1e-4)
    assert float(hi1) == pytest.approx(9.3484, abs=1e-4)
    # averages of 20 true chi-square(3) draws land inside the band 95% of the time
    rng = np.random.default_rng(1)
    averages = rng.chisquare(3, size=(20_000, 20)).mean(axis=1)
    lo, hi = chi2_band(3, 20)
    assert np.mean((averages >= lo) & (averages <= hi)) == pytest.approx(0.95, abs=0.01)


# --------------------------------------------------------------------------- noise that matches
@pytest.mark.parametrize("name", ["octagon", "loop"])
def test_filter_noise_matches_the_simulators_own(name):
    sim, arena = scenario(name, seed=4)
    run = simulate(sim, arena)
    noise = noise_for_simulation(sim)
    gt, dt = run.groundtruth, 1.0 / sim.controls_hz
    # recover each interval's true body twist from the exact arc the simulator integrates
    a = wrap_angle(np.diff(gt.pose[:, 2]))
    mid = gt.pose[:-1, 2] + a / 2
    dp = np.diff(gt.pose[:, :2], axis=0) / (dt * np.sinc(a / (2 * np.pi)))[:, None]
    body = np.column_stack(
        [
            np.cos(mid) * dp[:, 0] + np.sin(mid) * dp[:, 1],
            -np.sin(mid) * dp[:, 0] + np.cos(mid) * dp[:, 1],
            a / dt,
        ]
    )
    cmd = run.control_twist()[:-1]
    moving = np.any(cmd != 0, axis=1)
    measured = np.var(body[moving] - cmd[moving], axis=0)
    # a random walk of density M per second, held per interval: twist variance M / dt
    expected = np.diag(noise.motion_density()) / dt
    np.testing.assert_allclose(measured, expected, rtol=0.12)
    # and Q: range and bearing residuals against the truth
    det = run.detections
    pose, _ = interpolate_poses(gt, det.t)
    tags = np.array([arena.tag_map()[i] for i in det.tag_id.tolist()])
    d = tags - pose[:, :2]
    r_err = det.range - np.hypot(d[:, 0], d[:, 1])
    b_err = wrap_angle(det.bearing - np.arctan2(d[:, 1], d[:, 0]) + pose[:, 2])
    assert np.std(r_err) == pytest.approx(noise.sigma_range, rel=0.1)
    assert np.std(b_err) == pytest.approx(noise.sigma_bearing, rel=0.1)


def test_loop_scenario_is_a_long_loop_around_15_landmarks():
    sim, arena = scenario("loop", seed=0)
    run = simulate(sim, arena)
    assert len(arena.tags) == 15 and ring_arena().tag_positions().shape == (15, 2)
    assert 600 <= len(run.controls.t) <= 900  # a few hundred steps, as the issue asks
    assert set(run.detections.tag_id.tolist()) == set(range(15))  # every landmark seen
    np.testing.assert_allclose(run.groundtruth.pose[0], arena.nominal_start, atol=1e-12)
    frames = np.unique(run.detections.t)
    assert len(frames) > 0.95 * sim.camera_hz * run.controls.t[-1]  # rarely blind
    # the heading noise is what makes the loop hard: ~0.3 rad of drift over the lap, unobserved
    drift = noise_for_simulation(sim).sigma_theta * math.sqrt(run.controls.t[-1])
    assert 0.2 < drift < 0.6


# ---------------------------------------------------------------------------- one run's errors
def test_run_errors_agree_with_a_direct_computation():
    sim, arena = scenario("square", seed=3, laps=1)
    run = simulate(sim, arena)
    result = replay(run, noise_for_simulation(sim), start=run.groundtruth.pose[0])
    errors = run_errors(run, result)
    h, gt = result.history, run.groundtruth
    assert np.isnan(errors.nees_pose[0])  # the start is known exactly: no covariance yet
    for k in (5, 100, len(gt.t) - 1):
        event = np.flatnonzero(h.t <= gt.t[k])[-1]
        e = h.pose[event] - gt.pose[k]
        e[2] = (e[2] + np.pi) % (2 * np.pi) - np.pi
        P = h.pose_cov[event]
        assert errors.nees_pose[k] == pytest.approx(e @ np.linalg.inv(P) @ e, rel=1e-9)
        assert errors.nees_heading[k] == pytest.approx(e[2] ** 2 / P[2, 2], rel=1e-9)
        # in the invariant error's coordinates: ξ against T⁻¹ P T⁻ᵀ (`ekfslam.core.invariant`)
        est = h.pose[event]
        xi = pose_error(gt.pose[k], est)[0]
        P_xi = from_cartesian(P, est)
        assert errors.nees_pose_xi[k] == pytest.approx(xi @ np.linalg.solve(P_xi, xi), rel=1e-9)
    computed = np.isfinite(h.obs_nis)
    assert errors.nis_count.sum() == computed.sum()
    assert errors.nis_sum.sum() == pytest.approx(h.obs_nis[computed].sum())
    assert errors.landmark_count.sum() == len(h.obs_id)  # every sighting has an estimate
    assert errors.map_dof == 2 * len(result.landmarks) == 16


def test_nis_exposes_an_overconfident_observation_noise():
    sim, arena = scenario("octagon", seed=5, laps=1)
    run = simulate(sim, arena)
    right = noise_for_simulation(sim)
    tight = replace(right, sigma_range=right.sigma_range / 3)
    nis = []
    for noise in (right, tight):
        e = run_errors(run, replay(run, noise, FilterConfig(gate=None), start=arena.nominal_start))
        nis.append(e.nis_sum.sum() / e.nis_count.sum())
    assert 1.7 < nis[0] < 2.4  # chi-square(2) has mean 2
    assert nis[1] > 3 * nis[0]


# ---------------------------------------------------------------------------------- Monte Carlo
def test_octagon_is_consistent_for_both_linearizations():
    standard, fej = compare("octagon", runs=4)
    for r in (standard, fej):
        d = r.as_dict()
        lo, hi = d["band"]
        assert lo < d["nees_pose"]["mean"] < hi
        assert d["nees_pose"]["fraction_in_band"] >= 0.85
        assert 1.8 < d["nis"]["mean"] < 2.3  # every innovation pooled: a tight test
        assert d["nis"]["fraction_in_band"] >= 0.85
        assert d["band"] == pytest.approx(list(chi2_band(3, 4)))
        assert d["updates"]["initialised"] == 4 * 8  # every run maps all 8 tags
    # the very same simulated runs: the same sightings, only the linearization differs
    assert standard.counts.initialised == fej.counts.initialised
    assert not np.array_equal(standard.nees_pose, fej.nees_pose, equal_nan=True)


def test_standard_ekf_leaves_the_band_on_the_loop_and_fej_does_not():
    standard, fej = compare("loop", runs=10)
    second_half = standard.t > standard.t[-1] / 2
    assert fej.fraction_in_band("nees_pose") >= 0.9
    assert standard.fraction_in_band("nees_pose") < 0.8
    # the overconfidence is in the heading, and it grows along the loop
    assert np.nanmean(standard.nees_heading[second_half]) > 1.5 * np.nanmean(
        fej.nees_heading[second_half]
    )
    fig = plot_consistency([standard, fej])
    assert len(fig.axes) == 3 and all(ax.get_legend() for ax in fig.axes)


@pytest.mark.slow
def test_the_invariant_ekf_stays_in_the_chi2_band_on_the_loop():
    # Barrau & Bonnabel's right-invariant EKF: its Jacobians do not depend on the estimate
    # along the unobservable rotation, so it gains no heading information it cannot have
    standard, invariant = compare("loop", runs=20, linearizations=("standard", "invariant"))
    lo, hi = chi2_band(3, 20)
    d = invariant.as_dict()
    assert d["band"] == pytest.approx([lo, hi])
    assert lo < d["nees_pose"]["mean"] < hi
    assert invariant.fraction_in_band("nees_pose") >= 0.9
    assert standard.fraction_in_band("nees_pose") < 0.8
    second_half = standard.t > standard.t[-1] / 2
    assert np.nanmean(standard.nees_heading[second_half]) > 1.3 * np.nanmean(
        invariant.nees_heading[second_half]
    )
    assert invariant.counts.initialised == standard.counts.initialised  # the same runs


def test_runs_must_be_positive():
    with pytest.raises(ValueError, match="runs"):
        monte_carlo("square", runs=0)
    with pytest.raises(ValueError, match="scenario"):
        scenario("triangle")


# ------------------------------------------------------------------------------------ outliers
@pytest.mark.slow
def test_run_command_reports_the_rejected_outliers(tmp_path):
    sim, arena = scenario("square", seed=2, laps=1, outlier_range_rate=0.2)
    run = simulate(sim, arena)
    assert run.meta.simulation["outliers"]["range"] > 20
    write_run(run, tmp_path / "r")
    out = cli("run", str(tmp_path / "r"), "--json")
    assert out.returncode == 0, out.stderr
    reported = json.loads(out.stdout)["updates"]
    expected = replay(run, default_noise(run)).counts  # what the command line runs
    assert reported["rejected"] == expected.rejected > 10
    text = cli("run", str(tmp_path / "r")).stdout
    assert f"rejected {expected.rejected}," in text
