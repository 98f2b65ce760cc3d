"""The team filter against the textbook form: every step written with full-size lifted
Jacobians (F_x of each robot's block, H over the whole state) on generated teams and events,
and the state held to it to 1e-9. Also: a prediction leaves the other robots alone, a robot
sighting moves both robots, and Σ stays symmetric positive semi-definite."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ekfslam.core import models
from ekfslam.core.filter.history import Outcome
from ekfslam.core.filter.team import TeamEKF, _advance
from ekfslam.geometry import wrap_angle


class LiteralTeam:
    """The team's EKF, each step full size: Σ ← F Σ Fᵀ + Lᵀ R L, K = Σ Hᵀ S⁻¹ with H (2, d)."""

    def __init__(self) -> None:
        self.mu, self.Sigma = np.zeros(0), np.zeros((0, 0))
        self.rows, self.slot = {}, {}

    def _lift(self, first: int, width: int) -> np.ndarray:
        L = np.zeros((width, len(self.mu)))
        L[:, first : first + width] = np.eye(width)
        return L

    def add_robot(self, robot, pose, P):
        d = len(self.mu)
        self.rows[robot] = d
        self.mu = np.concatenate([self.mu, pose])
        Sigma = np.zeros((d + 3, d + 3))
        Sigma[:d, :d], Sigma[d:, d:] = self.Sigma, P
        self.Sigma = Sigma

    def predict(self, robot, u, M):
        r = self.rows[robot]
        L = self._lift(r, 3)
        pose = self.mu[r : r + 3]
        G, V = models.motion_jacobian(pose, u), models.motion_control_jacobian(pose)
        F = np.eye(len(self.mu)) + L.T @ (G - np.eye(3)) @ L  # eq. (7), lifted
        self.mu = self.mu + L.T @ (models.motion(pose, u) - pose)
        self.mu[r + 2] = wrap_angle(self.mu[r + 2])
        self.Sigma = F @ self.Sigma @ F.T + L.T @ (V @ M @ V.T) @ L  # eq. (9)

    def _correct(self, H, nu, Q, gate):
        S = H @ self.Sigma @ H.T + Q
        if nu @ np.linalg.solve(S, nu) > gate:
            return Outcome.REJECTED
        K = self.Sigma @ H.T @ np.linalg.inv(S)
        self.mu = self.mu + K @ nu
        for r in self.rows.values():
            self.mu[r + 2] = wrap_angle(self.mu[r + 2])
        self.Sigma = (np.eye(len(self.mu)) - K @ H) @ self.Sigma
        return Outcome.ACCEPTED

    def update(self, robot, z, landmark, Q, gate):
        r = self.rows[robot]
        pose = self.mu[r : r + 3]
        if landmark not in self.slot:
            m = models.inverse_observation(pose, z)
            G_r, G_z = models.inverse_observation_jacobians(pose, z)
            d = len(self.mu)
            A = np.vstack([np.eye(d), G_r @ self._lift(r, 3)])  # the new rows, as functions
            B = np.vstack([np.zeros((d, 2)), G_z])
            self.mu = np.concatenate([self.mu, m])
            self.Sigma = A @ self.Sigma @ A.T + B @ Q @ B.T
            self.slot[landmark] = d
            return Outcome.INITIALISED
        l = self.slot[landmark]
        m = self.mu[l : l + 2]
        H_r, H_l = models.observation_jacobians(pose, m)
        H = H_r @ self._lift(r, 3) + H_l @ self._lift(l, 2)
        nu = models.innovation(z, models.observation(pose, m))
        return self._correct(H, nu, Q, gate)

    def update_robot(self, a, b, z, Q, gate):
        ra, rb = self.rows[a], self.rows[b]
        pa, pb = self.mu[ra : ra + 3], self.mu[rb : rb + 3]
        H_a, H_b = models.robot_observation_jacobians(pa, pb)
        H = H_a @ self._lift(ra, 3) + H_b @ self._lift(rb, 3)
        nu = models.innovation(z, models.robot_observation(pa, pb))
        return self._correct(H, nu, Q, gate)


@st.composite
def scripts(draw):
    """A team of 2-4 robots and 20-60 events: predictions (batches), landmark sightings (of 5
    landmarks), robot sightings, in any order; the values drawn so no two points coincide."""
    n = draw(st.integers(2, 4))
    events = []
    for _ in range(draw(st.integers(20, 60))):
        kind = draw(st.sampled_from(["predict", "predict", "landmark", "robot"]))
        a = draw(st.integers(1, n))
        if kind == "predict":
            k = draw(st.integers(1, 4))
            us = draw(
                st.lists(
                    st.tuples(st.floats(-0.2, 0.2), st.floats(-0.05, 0.05), st.floats(-0.4, 0.4)),
                    min_size=k,
                    max_size=k,
                )
            )
            events.append(("predict", a, np.array(us)))
        elif kind == "landmark":
            events.append(
                (
                    "landmark",
                    a,
                    draw(st.integers(0, 4)),
                    draw(st.floats(0.5, 3.0)),
                    draw(st.floats(-3.0, 3.0)),
                )
            )
        else:
            b = draw(st.integers(1, n - 1))
            b += b >= a  # any robot but a
            events.append(("robot", a, b, draw(st.floats(0.5, 3.0)), draw(st.floats(-3, 3))))
    return n, events


M = np.diag([0.02**2, 0.01**2, 0.03**2])
Q = np.diag([0.1**2, 0.05**2])


@settings(max_examples=40, deadline=None)
@given(scripts(), st.sampled_from([math.inf, 9.21]))
def test_the_team_filter_is_the_textbook_form(script, gate):
    n, events = script
    fast, literal = TeamEKF(gate=gate, capacity=4), LiteralTeam()
    rng = np.random.default_rng(n)
    for robot in range(1, n + 1):
        pose = np.array([1.5 * robot, 0.7 * robot**2, 0.3 * robot - 1.0])
        A = rng.normal(size=(3, 3)) * 0.05
        fast.add_robot(robot, pose, A @ A.T)
        literal.add_robot(robot, pose.copy(), A @ A.T)
    for event in events:
        if event[0] == "predict":
            _, a, us = event
            fast.predict_many(a, us, np.ones(len(us)), M)
            for u in us:
                literal.predict(a, u, M)
            continue
        if event[0] == "landmark":
            _, a, landmark, r, phi = event
            got = fast.update(a, (r, phi), landmark, Q)
            want = literal.update(a, np.array([r, phi]), landmark, Q, gate)
        else:
            _, a, b, r, phi = event
            pa, pb = fast.pose(a), fast.pose(b)
            if math.hypot(*(pb[:2] - pa[:2])) < 0.05:
                continue
            got = fast.update_robot(a, b, (r, phi), Q)
            want = literal.update_robot(a, b, np.array([r, phi]), Q, gate)
        assert got == want
    assert fast.rows == literal.rows and fast.slot == literal.slot
    d = len(literal.mu)
    mu = fast.mu
    assert np.allclose(mu, literal.mu, rtol=1e-9, atol=1e-9)
    for r in fast.rows.values():
        assert abs(wrap_angle(mu[r + 2] - literal.mu[r + 2])) < 1e-9
    Sigma = fast.Sigma
    assert Sigma.shape == (d, d)
    assert np.allclose(Sigma, literal.Sigma, rtol=1e-8, atol=1e-10)
    assert np.array_equal(Sigma, Sigma.T)
    assert np.linalg.eigvalsh(Sigma).min() > -1e-9


def test_a_prediction_moves_one_robot_and_a_robot_sighting_moves_two():
    team = TeamEKF()
    for robot, pose in ((1, (0.0, 0.0, 0.0)), (2, (2.0, 0.0, math.pi)), (3, (0.0, 2.0, 0.0))):
        team.add_robot(robot, np.array(pose), np.eye(3) * 0.01)
    team.update(1, (1.0, 0.5), 7, Q)  # a landmark, correlated with robot 1 only
    before = team.mu
    team.predict_many(2, np.array([[0.1, 0.0, 0.1]]), [1.0], M)
    after = team.mu
    moved = np.flatnonzero(after != before)
    assert set(moved) <= {3, 4, 5}  # robot 2's rows only
    Sigma = team.Sigma
    assert np.all(Sigma[6:9, 3:6] == 0.0)  # robots 2 and 3 still uncorrelated
    z = models.robot_observation(team.pose(1), team.pose(2)) + np.array([0.05, 0.02])
    assert team.update_robot(1, 2, z, Q) == Outcome.ACCEPTED
    changed = np.abs(team.mu - after) > 1e-12
    assert changed[0:3].any() and changed[3:6].any()  # both robots moved
    assert not changed[6:9].any()  # robot 3 is correlated with neither
    assert changed[9:11].any()  # the landmark follows robot 1


def test_robots_on_one_another_and_names_are_refused():
    team = TeamEKF()
    team.add_robot(1, np.zeros(3))
    team.add_robot(2, np.zeros(3))
    assert team.update_robot(1, 2, (0.0, 0.0), Q) == Outcome.REFUSED
    with pytest.raises(ValueError, match="already in the team"):
        team.add_robot(1, np.zeros(3))
    with pytest.raises(ValueError, match="pose must be"):
        team.add_robot(3, np.zeros(2))


def _stepped(pose, P, us, dts, M, motion=models.ODOMETRY):
    """The batch one increment at a time, eqs. (6), (7), (9) on numpy arrays."""
    pose, P, G_all = np.array(pose, float), np.array(P, float), np.eye(3)
    for u, dt in zip(us, dts, strict=True):
        G, V = motion.F_x(pose, u, dt), motion.F_v(pose, u, dt)
        pose = motion.f(pose, u, dt)
        P = G @ P @ G.T + V @ (M * dt) @ V.T
        G_all = G @ G_all
    return pose, P, G_all


def test_a_batch_runs_the_generated_straight_line_step_and_equals_stepping():
    """The team predicts through `steps.advance` as generated straight-line code on floats (what
    made a MRCLAM team's replay 1.5-2x faster); a 2,000-row batch of MRCLAM-like odometry ends
    where stepping the models on numpy arrays does, to 1e-12, its correlations with it."""
    assert _advance(models.ODOMETRY, models.RANGE_BEARING)[1] is True
    rng = np.random.default_rng(7)
    dts = rng.uniform(0.005, 0.03, 2000)
    us = np.column_stack([0.2 * dts, 0.01 * dts, rng.normal(0.0, 0.5, 2000) * dts])
    team = TeamEKF()
    team.add_robot(1, np.array([0.5, -1.0, 3.0]), np.eye(3) * 1e-4)
    team.add_robot(2, np.array([1.0, 1.0, 0.0]), np.eye(3) * 1e-4)
    team.update(1, (1.0, 0.3), 4, Q)  # a landmark correlated with robot 1
    Sigma_before = team.Sigma
    team.predict_many(1, us[:700], dts[:700], M)
    team.predict_many(1, us[700:], dts[700:], M)  # two batches, one pending product
    pose, P, G_all = _stepped([0.5, -1.0, 3.0], Sigma_before[0:3, 0:3], us, dts, M)
    assert np.allclose(team.pose(1), pose, rtol=0, atol=1e-12)
    assert np.allclose(team.pose_covariance(1), P, rtol=1e-12, atol=1e-15)
    Sigma = team.Sigma
    assert np.allclose(Sigma[0:3, 6:8], G_all @ Sigma_before[0:3, 6:8], rtol=1e-12, atol=1e-15)
    assert np.array_equal(Sigma[3:6, 3:6], Sigma_before[3:6, 3:6])  # robot 2 did not move


def _branching_motion(pose, u, dt):
    if abs(u[2]) < 1e-9:  # a branch on a value: not straight-line code
        return models.motion(pose, (u[0], u[1], 0.0), dt)
    return models.motion(pose, u, dt)


def test_a_motion_model_with_a_branch_runs_advance_as_written():
    branching = models.MotionModel(
        f=_branching_motion,
        F_x=models.motion_jacobian,
        F_v=models.motion_control_jacobian,
        name="branching",
    )
    assert _advance(branching, models.RANGE_BEARING)[1] is False
    team = TeamEKF(motion=branching)
    team.add_robot(1, np.array([0.0, 0.0, 0.5]), np.eye(3) * 1e-4)
    us = np.array([[0.1, 0.0, 0.0], [0.1, 0.02, 0.3], [0.05, 0.0, -0.2]])
    dts = np.array([0.5, 0.25, 1.0])
    team.predict_many(1, us, dts, M)
    pose, P, _ = _stepped([0.0, 0.0, 0.5], np.eye(3) * 1e-4, us, dts, M, branching)
    assert np.allclose(team.pose(1), pose, atol=1e-14)
    assert np.allclose(team.pose_covariance(1), P, atol=1e-15)


def test_a_robot_placed_from_others_is_correlated_as_eq_12_says():
    """`add_robot(..., depends={p: A_p})`: the new rows are Σ_p A_p (the placed robots' rows),
    as a landmark's are G_r (its observer's): Σ' = J Σ Jᵀ + blockdiag(0, P) with the new rows
    of J the lifted A's, as the literal form writes it."""
    rng = np.random.default_rng(5)
    team, literal = TeamEKF(gate=None, capacity=4), LiteralTeam()
    for robot in (1, 2):
        pose = rng.normal(size=3)
        A = rng.normal(size=(3, 3)) * 0.1
        team.add_robot(robot, pose, A @ A.T)
        literal.add_robot(robot, pose.copy(), A @ A.T)
    team.update(1, (1.0, 0.3), 4, Q)
    literal.update(1, np.array([1.0, 0.3]), 4, Q, math.inf)
    team.update_robot(2, 1, (1.5, -0.2), Q)  # so robots 1 and 2 are correlated
    literal.update_robot(2, 1, np.array([1.5, -0.2]), Q, math.inf)
    team.predict_many(2, np.array([[0.1, 0.0, 0.2]]), [1.0], M)  # a pending prediction
    literal.predict(2, np.array([0.1, 0.0, 0.2]), M)
    A1, A2 = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
    P = np.diag([0.01, 0.02, 0.003])
    team.add_robot(3, [0.2, 0.4, 3.0], P, depends={1: A1, 2: A2})
    d = len(literal.mu)
    J = np.vstack([np.eye(d), A1 @ literal._lift(0, 3) + A2 @ literal._lift(3, 3)])
    want = J @ literal.Sigma @ J.T
    want[d:, d:] += P
    assert literal.rows == {1: 0, 2: 3}
    assert np.allclose(team.Sigma, want, rtol=1e-10, atol=1e-12)
    assert np.array_equal(team.Sigma, team.Sigma.T)
    assert np.linalg.eigvalsh(team.Sigma).min() > -1e-12
    with pytest.raises(ValueError, match="depends on robot 9"):
        team.add_robot(4, np.zeros(3), depends={9: np.eye(3)})
