"""The user's-loop benchmark, run tiny: every filter has a finite figure, and the ukfm
reimplementation and the package solve the same problem (no timings asserted)."""

from __future__ import annotations

import math

from benchmarks.loop import CONFIGS, PR, PR_OURS, UKFM, bench_loop, loop_table
from benchmarks.ukfm_slam2d import run_ukfm_ekf, simulate


def test_loop_bench_has_every_filter_and_finite_figures():
    r = bench_loop(runs=1, steps=40)
    assert set(r["us_per_step"]) == {*CONFIGS, UKFM, PR, PR_OURS}
    for name in [*CONFIGS, UKFM]:
        assert r["us_per_step"][name] > 0 and math.isfinite(r["ukfm_over"][name])
        assert r["position_rmse_m"][name] < 0.5  # 40 s of driving: both track the robot
    assert math.isfinite(r["pythonrobotics_over_ours"]) and r["position_rmse_m"][PR_OURS] < 1.0
    assert r["ukfm_over"][UKFM] == 1.0
    assert "| ukfm ekf (reimplemented) |" in loop_table(r)


def test_ukfm_world_sees_two_to_three_landmarks_a_step():
    world = simulate(0, 300)
    seen = (world.ys[:, :, 2] >= 0).sum(axis=1)
    assert 1.5 < seen.mean() < 4.0
    estimate = run_ukfm_ekf(world)
    assert abs(estimate[-1] - world.poses[-1])[:2].max() < 1.0
