"""The lab's exercises 7-9 (the NIS gate, the replay loop, eq. 17): each check names a typical
wrong answer, and the solution's replay reproduces the package's octagon Table 1 row."""

from __future__ import annotations

import re

import numpy as np

from ekfslam import EKFSLAM
from ekfslam.analysis import lab_checks as lc
from ekfslam.analysis.alignment import align_mean_distance
from ekfslam.core import models
from ekfslam.core.models import motion_noise
from ekfslam.core.noise import default_config, default_noise
from ekfslam.geometry import wrap_angle
from ekfslam.pipeline import replay
from ekfslam.teaching import map_exercises as mx
from tests.teaching.test_lab import LAB, defined, exercise_cells, octagon


def verdict(check, fn, capsys) -> str:
    assert check(fn) is False
    return capsys.readouterr().out


def _nis(z, z_hat, S, wrap=True):
    nu = z - z_hat
    if wrap:
        nu[1] = wrap_angle(float(nu[1]))
    return float(nu @ np.linalg.solve(S, nu))


def test_check_nis_gate_names_the_unwrapped_bearing_the_uninverted_S_and_ln_p(capsys) -> None:
    check = mx.check_nis_gate
    unwrapped = lambda z, zh, S, p: (_nis(z, zh, S, wrap=False), -2 * np.log(1 - p))  # noqa: E731

    def times_S(z, zh, S, p):
        nu = z - zh
        nu[1] = wrap_angle(float(nu[1]))
        return float(nu @ S @ nu), -2 * np.log(1 - p)

    ln_p = lambda z, zh, S, p: (_nis(z, zh, S), -2 * np.log(p))  # noqa: E731
    assert "bearing is not wrapped" in verdict(check, unwrapped, capsys)
    assert "multiplies by S" in verdict(check, times_S, capsys)
    out = verdict(check, ln_p, capsys)
    assert "uses ln p" in out and "9.2" not in out  # the right threshold is not given away


def test_the_gate_is_the_filters_2dof_quantile() -> None:
    from ekfslam.core.filter.config import CHI2_2DOF_99

    _, threshold = defined(exercise_cells()["7"], "nis_gate")(
        np.zeros(2), np.zeros(2), np.eye(2), 0.99
    )
    assert abs(threshold - CHI2_2DOF_99) < 1e-12 and abs(threshold - 9.2103) < 1e-4


def whole_intervals(run, ekf, noise, keep=lambda det_t: det_t == det_t):
    """Each control interval predicted whole, then the detections inside it (and those before
    the first control after the first interval)."""
    twist, t, det = run.control_twist(), run.controls.t, run.detections
    for i in range(len(t) - 1):
        dt = t[i + 1] - t[i]
        ekf.predict(twist[i] * dt, motion_noise(ekf.mu[:3], noise.motion_density() * dt))
        after = det.t > t[i] if i else np.ones(len(det.t), bool)
        mine = after & ((det.t <= t[i + 1]) | (i == len(t) - 2)) & keep(det.t)
        for k in np.flatnonzero(mine):
            ekf.update(int(det.tag_id[k]), (det.range[k], det.bearing[k]), noise.Q)


def test_check_replay_catches_the_order_lost_detections_and_a_wrong_R(capsys, monkeypatch) -> None:
    check = LAB["8"][1]
    assert "split the interval at each detection" in verdict(check, whole_intervals, capsys)
    right = defined(exercise_cells()["8"], "replay_loop")

    def skips_the_first(run, ekf, noise):  # the detections before the first control are lost
        t0 = run.controls.t[0]
        whole_intervals(run, ekf, noise, keep=lambda det_t: det_t > t0)

    assert re.search(
        r"fed \d+ of the run's \d+ detections", verdict(check, skips_the_first, capsys)
    )
    # the octagon's σx = σy, so an R without V would pass; an R per control row, not per second,
    # does not: M dt for dt = 0.05 s, not M (the octagon's pieces are all 0.05 s long, so this
    # is exactly an R not scaled by dt, and the check says so)
    real = models.motion_noise
    monkeypatch.setattr(models, "motion_noise", lambda pose, M: real(pose, 20.0 * M))
    on_the_octagon = lambda loop: lc.check_replay(loop, octagon())  # noqa: E731
    assert "builds each piece's R from M itself" in verdict(on_the_octagon, right, capsys)
    # an R wrong in another way is not one of the typical loops: the general verdict
    monkeypatch.setattr(models, "motion_noise", lambda pose, M: real(pose, 3.0 * M))
    assert "its own R" in verdict(check, right, capsys)


def test_the_solutions_replay_loop_reproduces_the_octagon_table1_row() -> None:
    run = octagon()
    ekf = EKFSLAM(run.meta.nominal_start, None, default_config(run))
    defined(exercise_cells()["8"], "replay_loop")(run, ekf, default_noise(run))
    want = replay(run)
    assert np.abs(ekf.mu - want.mu).max() < 1e-9 and np.abs(ekf.Sigma - want.Sigma).max() < 1e-12
    mine, package = lc.table1_row(lc.landmarks_of(ekf), run), lc.table1_row(want.landmarks, run)
    assert np.abs(mine - package).max() < 1e-9
    assert 0.0 < package[3] < 0.05  # the simulated octagon's mean error, m (about 5 mm)


def test_check_alignment_catches_the_wrong_sign_and_names_a_package_call(capsys) -> None:
    def flipped(X, Y):  # the solution's, θ0 negated
        x0, y0, theta0 = defined(exercise_cells()["9"], "align_map")(X, Y)
        return x0, y0, -theta0

    def package(X, Y):
        a = align_mean_distance(X, Y)
        return a.x0, a.y0, a.theta0

    check = lc.check_alignment
    assert "θ0 has the wrong sign" in verdict(check, flipped, capsys)
    assert "you called the package's align_mean_distance" in verdict(check, package, capsys)
