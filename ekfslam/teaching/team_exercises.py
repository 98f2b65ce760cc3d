"""Notebook 13's exercise: the robot-to-robot update, eqs. (13)-(16) with H on two pose blocks.

The student writes ``update_robot(mu, Sigma, a, b, z, Q) -> (mu, Sigma)``: robot a (rows 3a,
3a + 1, 3a + 2 of a team's joint state, the robots' blocks first, then the landmarks) sees robot
b's centre at z = (r, φ) with noise Q, and both poses (and, through Σ, the map) are corrected.
The right answer is the package's `ekfslam.core.filter.team.TeamEKF.update_robot` without a
gate: each case is a state TeamEKF reached through robots, landmark sightings, predictions and
sightings of one another, and the posterior TeamEKF gives from it. The judge
(`ekfslam.teaching.verdicts`) names the usual slips: the bearing innovation or a posterior
heading left unwrapped, H with the observer's block only (the landmark update reused), the
target's block with the wrong sign, a robot read from rows a..a + 2, Q left out of S.

Notebook 13 is not one of the graded lab's (02-07): this check runs in the notebook only.
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np

from ekfslam.core import models
from ekfslam.core.filter.team import TeamEKF
from ekfslam.core.models import robot_observation, robot_observation_jacobians
from ekfslam.geometry import wrap_angle
from ekfslam.teaching.verdicts import Array, Exercise, Wrong, as_array, attempt, close

#: The sightings' noise in the cases: 5 cm, 0.03 rad.
Q_TEAM = np.diag([0.05**2, 0.03**2])
#: The control noise of the cases' predictions (per increment).
M_TEAM = np.diag([0.02**2, 0.01**2, 0.02**2])


def update_robot_literal(
    mu: Array,
    Sigma: Array,
    a: int,
    b: int,
    z: Array,
    Q: Array,
    robots: int,
    *,
    wrap_innovation: bool = True,
    wrap_headings: bool = True,
    target_block: float = 1.0,
    rows: tuple[int, int] | None = None,
) -> tuple[Array, Array]:
    """Eqs. (13)-(16) written out full size for a state of `robots` robots: H (2, d) with robot
    a's block at rows 3a..3a + 2 and robot b's at 3b..3b + 2, K = Σ Hᵀ S⁻¹, μ + K ν (every
    robot's heading wrapped), (I - K H) Σ.

    The keyword arguments make the slips the judge recognises (all off for the right answer):
    the bearing innovation or the posterior headings not wrapped, the target's block scaled by
    `target_block` (0: left out; -1: its sign flipped), the blocks read from other `rows`.
    """
    ra, rb = (3 * a, 3 * b) if rows is None else rows
    d = mu.size
    pa, pb = mu[ra : ra + 3], mu[rb : rb + 3]
    H_a, H_b = robot_observation_jacobians(pa, pb)
    H = np.zeros((2, d))
    H[:, ra : ra + 3] += H_a
    H[:, rb : rb + 3] += target_block * H_b
    nu = np.asarray(z, dtype=float) - robot_observation(pa, pb)
    if wrap_innovation:
        nu[1] = wrap_angle(float(nu[1]))
    K = Sigma @ H.T @ np.linalg.inv(H @ Sigma @ H.T + Q)
    post = mu + K @ nu
    if wrap_headings:  # every robot's; a slip of `rows` wraps the two rows it took for them
        for first in range(0, 3 * robots, 3) if rows is None else rows:
            post[first + 2] = wrap_angle(float(post[first + 2]))
    return post, (np.eye(d) - K @ H) @ Sigma


def _random_team(rng: np.random.Generator, headings: list[float], landmarks: int) -> TeamEKF:
    """A TeamEKF that has seen some of everything: a robot per heading, at a random place with a
    random covariance; `landmarks` landmarks, each placed by a robot after a prediction; then
    two sightings of one robot by another, so every block of Σ is filled. The last robot never
    predicts nor observes (it may be seen), so its heading moves only through correlations."""
    team = TeamEKF(gate=None)
    for k, heading in enumerate(headings):
        A = rng.normal(size=(3, 3)) * [0.05, 0.05, 0.03]
        pose = [*rng.uniform(-1.5, 1.5, 2), heading]
        team.add_robot(k, pose, A @ A.T + 1e-4 * np.eye(3))
    movers = len(headings) - 1
    for j in range(landmarks):
        k = int(rng.integers(movers))
        us = rng.normal(0.0, [0.1, 0.02, 0.2], (3, 3))
        team.predict_many(k, us, np.ones(3), M_TEAM)  # M per second, one second a step
        team.update(k, [rng.uniform(0.5, 2.0), rng.uniform(-1.0, 1.0)], j, Q_TEAM)
    for _ in range(2):
        a = int(rng.integers(movers))
        b = int(rng.choice([k for k in range(len(headings)) if k != a]))
        z = robot_observation(team.pose(a), team.pose(b)) + rng.normal(0, [0.05, 0.03])
        team.update_robot(a, b, z, Q_TEAM)
    return team


def _case(team: TeamEKF, a: int, b: int, z: Array) -> dict:
    after = copy.deepcopy(team)
    after.update_robot(a, b, z, Q_TEAM)
    return {
        "mu": team.mu,
        "Sigma": team.Sigma,
        "a": a,
        "b": b,
        "z": np.asarray(z, dtype=float),
        "Q": Q_TEAM.copy(),
        "robots": len(team.rows),
        "want": (after.mu, after.Sigma),
    }


def _behind(rng: np.random.Generator) -> dict:
    """Robot 0 sees robot 1 right behind it: ẑ's bearing just below π, z's just above -π, so an
    unwrapped innovation is off by 2π. Robot 1 has mapped a landmark (it moves too)."""
    team = TeamEKF(gate=None)
    team.add_robot(0, [0.0, 0.0, 0.0], np.diag([0.02, 0.02, 0.01]) ** 2)
    team.add_robot(1, [-1.0, rng.uniform(0.001, 0.003), 0.5], np.diag([0.2, 0.2, 0.1]) ** 2)
    team.update(1, [0.8, 0.3], 0, Q_TEAM)
    z = np.array([1.03, wrap_angle(np.pi + rng.uniform(0.004, 0.008))])
    return _case(team, 0, 1, z)


def _turning_past_pi(rng: np.random.Generator) -> dict:
    """Robot 2, its heading just below π, sees robot 1, and the sighting turns its heading
    across π, so an unwrapped posterior heading shows (rows 6-8 and 3-5: reading robot a from
    rows a..a + 2 shows too)."""
    for _ in range(100):
        team = _random_team(rng, [rng.uniform(-3, 3), rng.uniform(-3, 3), np.pi - 1e-3], 2)
        mu, Sigma = team.mu, team.Sigma
        truth = robot_observation(mu[6:9], mu[3:6])
        for step in np.linspace(0.02, 0.4, 20):
            for sign in (1.0, -1.0):
                z = truth + np.array([0.0, sign * step])
                z[1] = wrap_angle(float(z[1]))
                post, _ = update_robot_literal(mu, Sigma, 2, 1, z, Q_TEAM, 3, wrap_headings=False)
                if post[8] > np.pi + 1e-3:
                    return _case(team, 2, 1, z)
    raise RuntimeError("no sighting turns the heading past π: the cases cannot be drawn")


def _cases(rng: np.random.Generator) -> list[dict]:
    """Two fixed geometries (behind the observer; a heading across π), then random teams of 2-4
    robots with 0-3 landmarks and a sighting of any robot by any other."""
    cases = [_behind(rng), _turning_past_pi(rng)]
    for robots, landmarks in ((2, 0), (3, 2), (4, 3), (3, 1)):
        team = _random_team(rng, list(rng.uniform(-np.pi, np.pi, robots)), landmarks)
        a, b = (int(k) for k in rng.choice(robots, 2, replace=False))
        z = robot_observation(team.pose(a), team.pose(b)) + rng.normal(0, [0.05, 0.03])
        z[1] = wrap_angle(float(z[1]))
        cases.append(_case(team, a, b, z))
    return cases


def _judge(call: Callable, case: dict) -> None:
    mu, Sigma, a, b, z, Q = (case[k] for k in ("mu", "Sigma", "a", "b", "z", "Q"))
    d = mu.size
    result = call(("μ", mu), ("Σ", Sigma), ("a", a), ("b", b), ("z", z), ("Q", Q))
    if not isinstance(result, tuple | list) or len(result) != 2:
        raise Wrong("update_robot should return the pair (mu, Sigma).")
    got_mu = as_array(result[0], (d,), "mu")
    got = as_array(result[1], (d, d), "Sigma")
    want_mu, want = case["want"]
    if not close(got_mu, want_mu):
        _diagnose(got_mu, "mean", case)
    if not close(got, want):
        if close(got, Sigma):
            raise Wrong("Σ is not updated.")
        if not close(got, got.T):
            raise Wrong("your posterior Σ is not symmetric.")
        _diagnose(got, "covariance", case)


def _diagnose(got: Array, which: str, case: dict) -> None:
    """Raise the slip that gives `got` (the posterior mean or covariance), else a plain Wrong."""
    mu, Sigma, a, b, z, Q, robots = (case[k] for k in ("mu", "Sigma", "a", "b", "z", "Q", "robots"))
    part = 0 if which == "mean" else 1

    def gives(**slip) -> bool:
        noise = slip.pop("Q", Q)
        try:
            made = update_robot_literal(mu, Sigma, a, b, z, noise, robots, **slip)[part]
        except (models.DegenerateGeometry, np.linalg.LinAlgError):  # no such slip here
            return False
        return close(got, made)

    if part == 0:
        headings = np.zeros(mu.size, dtype=bool)
        headings[2 : 3 * robots : 3] = True
        if gives(wrap_innovation=False):
            raise Wrong(
                "your bearing innovation z - ẑ is not wrapped: with the other robot behind the "
                "observer it is off by 2π."
            )
        wrapped = got.copy()
        wrapped[headings] = [wrap_angle(float(h)) for h in got[headings]]
        if close(wrapped, case["want"][0]):
            raise Wrong("a posterior heading is not wrapped to [-π, π).")
    if gives(target_block=0.0):
        raise Wrong(
            "your H has only the observer's block: the target's position is in ẑ too, so H has "
            "a second block, ∂ẑ/∂target (eq. 14's landmark block with a zero heading column), "
            "and the sighting moves both robots."
        )
    if gives(target_block=-1.0):
        raise Wrong(
            "the target's block of H has the wrong sign: δ = target - observer, so ∂ẑ/∂target's "
            "position columns are minus ∂ẑ/∂observer's."
        )
    if (a, b) != (3 * a, 3 * b) and gives(rows=(a, b)):
        raise Wrong(
            "your update reads robot a from rows a, a + 1, a + 2; its pose is rows 3a, 3a + 1, "
            "3a + 2 (three rows per robot, the robots first)."
        )
    if gives(Q=0 * Q):
        raise Wrong("the measurement noise Q is missing from S = H Σ Hᵀ + Q.")
    if part == 0:
        raise Wrong("the posterior mean is wrong (eqs. 15-16).")
    raise Wrong("the posterior covariance is wrong (eq. 16).")


UPDATE_ROBOT_EXERCISE = Exercise(
    "1",
    "update_robot",
    _cases,
    _judge,
    allowed=lambda: (
        models.robot_observation,
        models.robot_observation_jacobians,
        models.observation,
        models.observation_jacobians,
        models.innovation,
        wrap_angle,
    ),
)


def check_update_robot(update_robot: Callable[..., object]) -> bool:
    """Notebook 13's exercise: ``update_robot(mu (d,), Sigma (d, d), a, b, z (2,), Q (2, 2)) ->
    (mu, Sigma)``, robot a's sighting z = (r, φ) of robot b's centre, eqs. (13)-(16) with H
    non-zero on both robots' pose blocks (rows 3a..3a + 2 and 3b..3b + 2). It may use the model
    (`models.robot_observation`, `robot_observation_jacobians`) and `wrap_angle`; it is compared
    with `TeamEKF.update_robot` on fixed and random team states. Prints one verdict; True when
    every case agrees."""
    return attempt(UPDATE_ROBOT_EXERCISE, update_robot)
