"""Notebook 13's check of the robot-to-robot update: a right answer passes on the notebook's
cases and on cases drawn from other seeds; a stub is "not done yet"; each usual slip fails
with its own message; the package's TeamEKF called in place of the student's own trips."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from ekfslam.core import models
from ekfslam.core.filter.team import TeamEKF
from ekfslam.geometry import wrap_angle
from ekfslam.teaching import team_exercises as tx
from ekfslam.teaching.verdicts import RNG_SEED, run_exercise


def answer(
    mu,
    Sigma,
    a,
    b,
    z,
    Q,
    wrap_innovation=True,
    wrap_headings=True,
    target_block=1.0,
    by_index=False,
    noise=True,
):
    """A student's update, right with the defaults; each option one slip (written here, not
    taken from the package: the tripwire would see the package's code)."""
    ra, rb = (a, b) if by_index else (3 * a, 3 * b)
    pa, pb = mu[ra : ra + 3], mu[rb : rb + 3]
    H_a, H_b = models.robot_observation_jacobians(pa, pb)
    H = np.zeros((2, mu.size))
    H[:, ra : ra + 3] += H_a
    H[:, rb : rb + 3] += target_block * H_b
    nu = z - models.robot_observation(pa, pb)
    if wrap_innovation:
        nu[1] = wrap_angle(nu[1])
    K = Sigma @ H.T @ np.linalg.inv(H @ Sigma @ H.T + (Q if noise else 0 * Q))
    mu = mu + K @ nu
    if wrap_headings:
        for r in (ra, rb):
            mu[r + 2] = wrap_angle(mu[r + 2])
    return mu, (np.eye(mu.size) - K @ H) @ Sigma


def right(mu, Sigma, a, b, z, Q):
    return answer(mu, Sigma, a, b, z, Q)


def slip(**how):
    return lambda mu, Sigma, a, b, z, Q: answer(mu, Sigma, a, b, z, Q, **how)


def stub(mu, Sigma, a, b, z, Q):
    """The notebook's stub."""
    # YOUR CODE HERE


def calls_the_package(mu, Sigma, a, b, z, Q):
    team = TeamEKF(gate=None)
    for k in range(max(a, b) + 1):
        team.add_robot(k, mu[3 * k : 3 * k + 3], Sigma[3 * k : 3 * k + 3, 3 * k : 3 * k + 3])
    team.update_robot(a, b, z, Q)
    return np.concatenate([team.mu, mu[team.d :]]), Sigma


def verdict(fn, seed=RNG_SEED):
    cases = tx.UPDATE_ROBOT_EXERCISE.make_cases(np.random.default_rng(seed))
    return run_exercise(tx.UPDATE_ROBOT_EXERCISE, fn, cases)


@pytest.mark.parametrize("seed", [RNG_SEED, 0, 1, 2, 3])
def test_the_right_answer_passes_and_the_cases_are_teamekfs(seed) -> None:
    v = verdict(right, seed)
    assert v.right, v.line
    for case in tx.UPDATE_ROBOT_EXERCISE.make_cases(np.random.default_rng(seed)):
        mu, Sigma = tx.update_robot_literal(
            *(case[k] for k in ("mu", "Sigma", "a", "b", "z", "Q", "robots"))
        )
        want_mu, want = case["want"]
        assert np.allclose(mu, want_mu, rtol=0, atol=1e-12)
        assert np.allclose(Sigma, want, rtol=0, atol=1e-12)


def test_the_check_prints_right_and_returns_true(capsys) -> None:
    assert tx.check_update_robot(right)
    assert "Exercise 1: right on every test case" in capsys.readouterr().out


def test_the_stub_is_not_done(capsys) -> None:
    assert tx.check_update_robot(stub) is False
    assert "Exercise 1: not done yet" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("answer", "message"),
    [
        (slip(wrap_innovation=False), "bearing innovation z - ẑ is not wrapped"),
        (slip(wrap_headings=False), "posterior heading is not wrapped"),
        (slip(target_block=0.0), "only the observer's block"),
        (slip(target_block=-1.0), "wrong sign"),
        (slip(by_index=True), "rows 3a, 3a + 1, 3a + 2"),
        (slip(noise=False), "Q is missing"),
        (lambda mu, Sigma, a, b, z, Q: (right(mu, Sigma, a, b, z, Q)[0], Sigma), "not updated"),
        (
            lambda mu, Sigma, a, b, z, Q: (right(mu, Sigma, a, b, z, Q)[0], np.triu(Sigma)),
            "not symmetric",
        ),
    ],
)
def test_each_slip_fails_with_its_message(answer, message) -> None:
    v = verdict(answer)
    assert not v.right and v.score < 1.0, v.line
    assert message in v.line, v.line


def test_a_copy_of_the_first_case_is_judged_alike() -> None:
    """The cases do not share arrays: a function that changes its inputs is told so."""

    def changes_mu(mu, Sigma, a, b, z, Q):
        out = right(mu, Sigma, a, b, z, Q)
        mu[0] += 1.0
        return out

    v = verdict(changes_mu)
    assert "changed the μ it was given" in v.line, v.line
    cases = tx.UPDATE_ROBOT_EXERCISE.make_cases(np.random.default_rng(RNG_SEED))
    assert verdict(right, RNG_SEED).right and copy.deepcopy(cases)[0]["a"] == 0


def test_calling_the_package_trips() -> None:
    v = verdict(calls_the_package)
    assert v.score == 0 and "you called the package's" in v.line, v.line
