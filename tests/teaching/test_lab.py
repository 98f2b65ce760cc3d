"""The lab: the student notebooks are current, every solution passes its check, every stub is
"not done yet", and each check names a typical wrong answer (without the right value)."""

from __future__ import annotations

import functools
import json
import re

import numpy as np
import pytest
import sympy as sp

from ekfslam import EKFSLAM
from ekfslam.analysis import lab_checks as lc
from ekfslam.core.models import motion, motion_control_jacobian, motion_jacobian
from ekfslam.core.steps import new_landmark_step, predict_step, update_steps
from ekfslam.errors import InputError
from ekfslam.geometry import wrap_angle
from ekfslam.logs.runlog import read_run
from ekfslam.teaching import exercises as ex
from ekfslam.teaching import make_lab
from ekfslam.teaching import map_exercises as mx
from ekfslam.teaching.derivations import dtheta, du_x, du_y, m_x, m_y, theta, x, y
from ekfslam.teaching.reference import LiteralEKFSLAM

# exercise -> (the function its cell defines, its check)
LAB = {
    "1a": ("twist_from_wheels", ex.check_twist),
    "1b": ("twist_covariance", ex.check_twist_covariance),
    "2a": ("derive_motion_jacobians", ex.check_motion_jacobians),
    "2b": ("motion_noise_R", ex.check_motion_noise),
    "3": ("predict", ex.check_predict),
    "4a": ("derive_observation", mx.check_observation_model),
    "4b": ("predict_z", mx.check_predicted_observation),
    "5": ("add_landmark", mx.check_new_landmark),
    "6a": ("joseph", mx.check_joseph),
    "6b": ("update", mx.check_update),
    "7": ("nis_gate", mx.check_nis_gate),
    "8": ("replay_loop", lambda loop: lc.check_replay(loop, octagon())),
    "9": ("align_map", lc.check_alignment),
}


@functools.cache
def octagon():
    """The seed's octagon run, whose Table 1 row exercise 8 reproduces."""
    return read_run(make_lab.NOTEBOOKS.parent / "data" / "runs" / "octagon-2laps")


def exercise_cells() -> dict[str, str]:
    """exercise -> the source of the code cell that holds its solution, from every source."""
    cells = {}
    for path in sorted(make_lab.SOLUTIONS.glob("*.ipynb")):
        for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
            text = "".join(cell["source"])
            for n in re.findall(r"# BEGIN SOLUTION exercise (\w+)", text):
                cells[n] = text
    return cells


def defined(source: str, name: str):
    namespace = {"np": np}
    exec(compile(source, f"<exercise cell {name}>", "exec"), namespace)
    return namespace[name]


def test_the_student_notebooks_are_current() -> None:
    assert make_lab.stale() == [], "run python -m ekfslam.teaching.make_lab"
    assert sorted(exercise_cells()) == sorted(LAB)


@pytest.mark.parametrize("n", sorted(LAB))
def test_every_solution_passes_and_every_stub_is_not_done_yet(n: str, capsys) -> None:
    name, check = LAB[n]
    source = exercise_cells()[n]
    assert check(defined(source, name)) is True
    assert f"Exercise {n}: right on every test case" in capsys.readouterr().out
    stub = make_lab.strip_solutions(source)
    assert f'raise NotImplementedError("exercise {n}")' in stub and "SOLUTION" not in stub
    assert check(defined(stub, name)) is False
    assert f"Exercise {n}: not done yet" in capsys.readouterr().out


def test_the_jacobians_are_derived_by_sympy_in_the_notebook() -> None:
    assert ".jacobian(" in exercise_cells()["2a"]
    assert ".jacobian(" in exercise_cells()["4a"]


def test_strip_solutions_keeps_the_indentation_and_refuses_unmatched_markers() -> None:
    source = (
        "def f():\n    '''doc'''\n    # BEGIN SOLUTION exercise 7\n    return 1\n"
        "    # END SOLUTION\nf"
    )
    assert make_lab.strip_solutions(source) == (
        "def f():\n    '''doc'''\n    raise NotImplementedError(\"exercise 7\")\nf"
    )
    answer = "# BEGIN SOLUTION answer\n# STUB: a = None  # m\na = 3.0\n# END SOLUTION\ncheck(a)"
    assert make_lab.strip_solutions(answer) == "a = None  # m\ncheck(a)"
    with pytest.raises(InputError, match="cell:2: an answer block needs its # STUB: lines"):
        make_lab.strip_solutions("# BEGIN SOLUTION answer\n# END SOLUTION")
    with pytest.raises(InputError, match="exercise 7 has no END SOLUTION"):
        make_lab.strip_solutions("# BEGIN SOLUTION exercise 7\nx = 1")
    with pytest.raises(InputError, match="cell:1: END SOLUTION without a BEGIN"):
        make_lab.strip_solutions("# END SOLUTION")


def test_make_lab_check_says_current(capsys) -> None:
    assert make_lab.main(["--check"]) == 0
    assert capsys.readouterr().out == ""


# --- each check names a typical wrong answer ----------------------------------------------------


def verdict(check, fn, capsys) -> str:
    assert check(fn) is False
    return capsys.readouterr().out


def right_twist(w, g):
    r, k = g.wheel_radius, g.lx + g.ly
    w1, w2, w3, w4 = w
    return r / 4 * np.array([w1 + w2 + w3 + w4, -w1 + w2 + w3 - w4, (-w1 + w2 - w3 + w4) / k])


def test_check_twist_names_the_wrong_sign_factor_and_entry(capsys) -> None:
    flipped = lambda w, g: right_twist(w, g) * [1, -1, 1]  # noqa: E731
    assert "vy has the wrong sign for every wheel" in verdict(ex.check_twist, flipped, capsys)
    no_k = lambda w, g: right_twist(w, g) * [1, 1, g.lx + g.ly]  # noqa: E731
    assert "ωz has the right signs but the wrong factor" in verdict(ex.check_twist, no_k, capsys)
    one = lambda w, g: right_twist([w[0], w[1], -w[2], w[3]], g)  # noqa: E731
    out = verdict(ex.check_twist, one, capsys)
    assert "J[0, 2] (row vx, column ω3 (rear-left)) has the wrong sign" in out
    assert "0.0075" not in out  # the entry's value is not given away
    numbers = lambda w, g: right_twist(w, ex.MecanumGeometry())  # noqa: E731
    assert "right for the default robot only" in verdict(ex.check_twist, numbers, capsys)


def test_check_twist_covariance_catches_sigma_for_variance(capsys) -> None:
    def std(sigma, g):
        J = g.wheels_to_twist_matrix
        return J @ np.diag(sigma) @ J.T

    assert "needs variances" in verdict(ex.check_twist_covariance, std, capsys)


def test_check_motion_jacobians_names_the_entry(capsys) -> None:
    def wrong_sign():  # +Δuy sin θ in x: G[0, 2] and V[0, 1] are off
        f = [x + du_x * sp.cos(theta) + du_y * sp.sin(theta)]
        f += [y + du_x * sp.sin(theta) + du_y * sp.cos(theta), theta + dtheta]
        f = sp.Matrix(f)
        return f.jacobian([x, y, theta]), f.jacobian([du_x, du_y, dtheta])

    assert "G[0, 2] (row x, column θ) is wrong" in verdict(
        ex.check_motion_jacobians, wrong_sign, capsys
    )

    def swapped():
        G, V = defined(exercise_cells()["2a"], "derive_motion_jacobians")()
        return V, G

    assert "G and V are swapped" in verdict(ex.check_motion_jacobians, swapped, capsys)
    assert "which is not a pose or control symbol" in verdict(
        ex.check_motion_jacobians, lambda: (sp.Matrix([[sp.Symbol("a")]]), None), capsys
    )


def test_check_motion_noise_catches_the_unrotated_and_the_transposed(capsys) -> None:
    assert "R equals M" in verdict(ex.check_motion_noise, lambda pose, M: M, capsys)

    def transposed(pose, M):
        V = motion_control_jacobian(pose)
        return V.T @ M @ V

    assert "Vᵀ M V instead of V M Vᵀ" in verdict(ex.check_motion_noise, transposed, capsys)


def test_check_predict_names_the_forgotten_block(capsys) -> None:
    def no_wrap(mu, S, u, R):
        mu2, S2 = predict_step(mu, S, u, R)
        mu2[2] = mu[2] + u[2]
        return mu2, S2

    def no_cross(mu, S, u, R):
        mu2, S2 = predict_step(mu, S, u, R)
        S2[:3, 3:], S2[3:, :3] = S[:3, 3:], S[3:, :3]
        return mu2, S2

    def after(mu, S, u, R):
        mu2 = mu.copy()
        mu2[:3] = motion(mu[:3], u)
        G = motion_jacobian(mu2[:3], u)
        S = S.copy()
        S[:3, :3] = G @ S[:3, :3] @ G.T + R
        S[:3, 3:] = G @ S[:3, 3:]
        S[3:, :3] = S[:3, 3:].T
        return mu2, S

    def half(mu, S, u, R):
        mu2, S2 = predict_step(mu, S, u, R)
        S2[3:, :3] = S[3:, :3]
        return mu2, S2

    check = ex.check_predict
    assert "your heading is not wrapped" in verdict(check, no_wrap, capsys)
    assert "cross-covariance Σ[r, m] is not updated" in verdict(check, no_cross, capsys)
    noise_free = lambda mu, S, u, R: predict_step(mu, S, u, 0 * R)  # noqa: E731
    assert "the motion noise R is missing" in verdict(check, noise_free, capsys)
    assert "evaluated at the pose after the motion" in verdict(check, after, capsys)
    assert "Σ must stay symmetric" in verdict(check, half, capsys)
    assert "should return the pair" in verdict(check, lambda mu, S, u, R: mu, capsys)
    crash = lambda mu, S, u, R: mu[99]  # noqa: E731
    assert "your function raised IndexError" in verdict(check, crash, capsys)


def test_predict_step_is_the_filters_and_the_literal_prediction() -> None:
    pose, P0 = [0.1, -0.2, 3.1], np.diag([1e-4, 2e-4, 1e-3])
    Q = np.diag([0.03**2, 0.03**2])
    fast, literal = EKFSLAM(pose, P0), LiteralEKFSLAM(pose, P0)
    for f in (fast, literal):
        f.update(0, [1.0, 0.2], Q)
        f.update(1, [0.8, -0.5], Q)
    mu, Sigma = fast.mu.copy(), fast.Sigma.copy()
    u, R = np.array([0.05, 0.01, 0.2]), np.diag([1e-5, 2e-5, 4e-5])
    fast.predict(u, R)
    literal.predict(u, R)
    mu2, Sigma2 = predict_step(mu, Sigma, u, R)
    assert -np.pi <= mu2[2] < 0  # 3.1 + 0.2 wrapped
    np.testing.assert_allclose(mu2, fast.mu, atol=1e-12)
    np.testing.assert_allclose(Sigma2, fast.Sigma, atol=1e-12)
    np.testing.assert_allclose(Sigma2, literal.Sigma, atol=1e-12)


def test_make_lab_refuses_a_broken_source_in_one_line(monkeypatch, tmp_path, capsys) -> None:
    (tmp_path / "solutions").mkdir()
    cell = {"cell_type": "code", "metadata": {}, "source": ["# BEGIN SOLUTION exercise 4\n"]}
    (tmp_path / "solutions" / "04-x.ipynb").write_text(json.dumps({"cells": [cell]}))
    (tmp_path / "solutions" / "05-y.ipynb").write_text("{not json")
    monkeypatch.setattr(make_lab, "NOTEBOOKS", tmp_path)
    monkeypatch.setattr(make_lab, "SOLUTIONS", tmp_path / "solutions")
    assert make_lab.main([]) == 2
    err = capsys.readouterr().err
    assert err == "make_lab: 04-x.ipynb cell 0: exercise 4 has no END SOLUTION\n"
    assert not (tmp_path / "04-x.ipynb").exists()  # nothing written half-way


def test_check_observation_model_catches_the_seeds_arctan(capsys) -> None:
    def seed():  # eq. (13) as printed: arctan(δy/δx)
        dx, dy = m_x - x, m_y - y
        z = sp.Matrix([sp.sqrt(dx**2 + dy**2), sp.atan(dy / dx) - theta])
        return z, z.jacobian([x, y, theta]), z.jacobian([m_x, m_y])

    out = verdict(mx.check_observation_model, seed, capsys)
    assert "off by π when the landmark is behind (δx < 0): use atan2" in out

    def sign():  # +θ: the bearing and H_pose[1, 2] are off
        dx, dy = m_x - x, m_y - y
        z = sp.Matrix([sp.sqrt(dx**2 + dy**2), sp.atan2(dy, dx) + theta])
        return z, z.jacobian([x, y, theta]), z.jacobian([m_x, m_y])

    assert "the bearing ẑ[1] is wrong" in verdict(mx.check_observation_model, sign, capsys)


def test_check_predicted_observation_catches_the_missing_wrap(capsys) -> None:
    def unwrapped(pose, m):
        dx, dy = m[0] - pose[0], m[1] - pose[1]
        return np.array([np.hypot(dx, dy), np.arctan2(dy, dx) - pose[2]])

    out = verdict(mx.check_predicted_observation, unwrapped, capsys)
    assert "your bearing is not wrapped to [-π, π)" in out


def test_check_new_landmark_names_the_missing_cross_covariance(capsys) -> None:
    def zero(mu, S, z, Q):  # PythonRobotics #191
        mu2, S2 = new_landmark_step(mu, S, z, Q)
        d = mu.size
        S2[d:, :d], S2[:d, d:] = 0.0, 0.0
        return mu2, S2

    def robot_only(mu, S, z, Q):
        mu2, S2 = new_landmark_step(mu, S, z, Q)
        d = mu.size
        S2[d:, 3:d], S2[3:d, d:] = 0.0, 0.0
        return mu2, S2

    check = mx.check_new_landmark
    assert "the cross-covariance of the new landmark is missing" in verdict(check, zero, capsys)
    out = verdict(check, robot_only, capsys)
    assert "cross-covariance with the older landmarks is missing or wrong" in out


def test_new_landmark_step_is_the_filters_initialisation() -> None:
    Q = np.diag([9e-4, 4e-3])
    fast = EKFSLAM([0.1, -0.2, 0.4], np.diag([1e-4, 2e-4, 1e-3]))
    fast.update(0, [1.0, 0.2], Q)
    fast.predict([0.05, 0.01, 0.1], np.diag([1e-5, 1e-5, 4e-5]))
    mu, Sigma = fast.mu.copy(), fast.Sigma.copy()
    fast.update(1, [0.8, -0.5], Q)  # init="inverse": placed, not corrected
    mu2, Sigma2 = new_landmark_step(mu, Sigma, [0.8, -0.5], Q)
    np.testing.assert_allclose(mu2, fast.mu, atol=1e-12)
    np.testing.assert_allclose(Sigma2, fast.Sigma, atol=1e-12)


def test_check_update_names_the_unwrapped_innovation_and_the_missing_Q(capsys) -> None:
    def unwrapped(mu, S, j, z, Q):  # the seed's eq. (16)
        s = update_steps(mu, S, j, z, Q)
        mu2 = mu + s.K @ (z - s.z_hat)
        mu2[2] = wrap_angle(float(mu2[2]))
        return mu2, s.Sigma_joseph

    def no_Q(mu, S, j, z, Q):
        s = update_steps(mu, S, j, z, 0 * Q)
        return s.mu_post, s.Sigma_joseph

    check = mx.check_update
    assert "bearing innovation z - ẑ is not wrapped" in verdict(check, unwrapped, capsys)
    assert "Q is missing from S = H Σ Hᵀ + Q" in verdict(check, no_Q, capsys)


def _short_form(Sigma, K, H, Q):  # the seed's eq. (16)
    return (np.eye(len(Sigma)) - K @ H) @ Sigma


def test_check_joseph_tells_the_seeds_short_form_the_missing_KQK_and_the_transposes(capsys) -> None:
    def no_KQK(Sigma, K, H, Q):
        I_KH = np.eye(len(Sigma)) - K @ H
        return I_KH @ Sigma @ I_KH.T

    def transposed(Sigma, K, H, Q):
        I_KH = np.eye(len(Sigma)) - K @ H
        return I_KH.T @ Sigma @ I_KH + K @ Q @ K.T

    check = mx.check_joseph
    out = verdict(check, _short_form, capsys)
    assert "that is the seed's (I - KH)Σ, which is right only for the optimal gain" in out
    assert "with 1.2 K" in out
    assert "K Q Kᵀ is missing" in verdict(check, no_KQK, capsys)
    assert "transposes are on the wrong side" in verdict(check, transposed, capsys)


def _exercise_6(*edits: tuple[str, str]) -> dict:
    """The names exercise 6's cell defines, with each (old, new) text replaced first."""
    source = exercise_cells()["6b"]
    for old, new in edits:
        assert source.count(old) == 1, old
        source = source.replace(old, new)
    namespace = {"np": np}
    exec(compile(source, "<exercise cell 6>", "exec"), namespace)
    return namespace


JOSEPH = "return I_KH @ Sigma @ I_KH.T + K @ Q @ K.T"
SHORT = "return I_KH @ Sigma"


def test_the_short_form_passes_the_update_but_not_joseph(capsys) -> None:
    cell = _exercise_6((JOSEPH, SHORT))
    assert mx.check_update(cell["update"]) is True  # the optimal gain: both forms agree
    assert mx.check_joseph(cell["joseph"]) is False  # other gains: 6a tells them apart


def test_check_update_says_when_the_update_does_not_use_joseph_or_joseph_is_a_stub(capsys) -> None:
    inline = "return mu, (np.eye(d) - K @ H) @ Sigma"
    cell = _exercise_6(("return mu, joseph(Sigma, K, H, Q)  # exercise 6a", inline))
    out = verdict(mx.check_update, cell["update"], capsys)
    assert "does not call your joseph(Sigma, K, H, Q) of exercise 6a" in out
    cell = _exercise_6(("I_KH = np.eye(len(Sigma)) - K @ H", "raise NotImplementedError"))
    assert "exercise 6a is not done yet" in verdict(mx.check_update, cell["update"], capsys)
