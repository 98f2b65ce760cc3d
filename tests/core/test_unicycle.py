"""A unicycle driven by rates (v, ω), written here through the public API alone (issue 37,
item 2): a control of 2 numbers integrated over each step's dt, its Jacobians seeing the control
and dt (F_v(pose, u, dt) = ∂f/∂(v, ω)), the filter in both backends matched to the literal F_x
reference, the Jacobians to finite differences."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.models import RANGE_BEARING, MotionModel
from ekfslam.errors import ConfigError
from ekfslam.geometry import wrap_angle
from ekfslam.teaching.finite_differences import jacobian_errors
from ekfslam.teaching.reference import LiteralEKFSLAM


def drive(pose, u, dt):
    """The pose after driving at v (m/s) and turning at ω (rad/s) for dt s, along the chord at
    the mid-step heading (second order in ω dt, no branch at ω = 0)."""
    v, w = u[0], u[1]
    heading = pose[2] + 0.5 * w * dt
    return np.array(
        (
            pose[0] + v * dt * math.cos(heading),
            pose[1] + v * dt * math.sin(heading),
            wrap_angle(pose[2] + w * dt),
        )
    )


def drive_jacobian(pose, u, dt):
    """∂f/∂pose (3, 3), eq. (7)'s G for this f."""
    heading = pose[2] + 0.5 * u[1] * dt
    d = u[0] * dt
    return np.array(
        ((1.0, 0.0, -d * math.sin(heading)), (0.0, 1.0, d * math.cos(heading)), (0.0, 0.0, 1.0))
    )


def drive_control_jacobian(pose, u, dt):
    """∂f/∂(v, ω) (3, 2): the control noise's way into the pose, R = V M Vᵀ."""
    heading = pose[2] + 0.5 * u[1] * dt
    c, s = math.cos(heading), math.sin(heading)
    half = 0.5 * u[0] * dt * dt
    return np.array(((dt * c, -half * s), (dt * s, half * c), (0.0, dt)))


UNICYCLE = MotionModel(
    f=drive, F_x=drive_jacobian, F_v=drive_control_jacobian, name="unicycle", control_size=2
)
M = np.diag([0.02, 0.01])  # (v, ω) covariance per second of driving
Q = np.diag([0.05, 0.01]) ** 2


def events(seed: int, steps: int = 120):
    """A drive among 6 landmarks: rates (v, ω) with dt varying, the turn exactly zero every
    fourth step, two range-bearing sightings a step."""
    rng = np.random.default_rng(seed)
    marks = rng.uniform(-4.0, 4.0, size=(6, 2))
    pose = np.array([0.0, 0.0, 0.1])
    t = 0.0
    for k in range(steps):
        dt = rng.uniform(0.05, 0.2)
        u = np.array([rng.uniform(0.2, 0.6), 0.0 if k % 4 == 0 else rng.uniform(-0.6, 0.6)])
        pose = drive(pose, u, dt)
        t += dt
        yield ("predict", u + rng.normal(0, np.sqrt(np.diag(M) * dt)), dt, t)
        for j in rng.choice(6, size=2, replace=False):
            d = marks[j] - pose[:2]
            z = np.array((math.hypot(*d), wrap_angle(math.atan2(d[1], d[0]) - pose[2])))
            yield ("update", int(j), z + rng.normal(0, (0.05, 0.01)), t)


def test_the_unicycles_jacobians_are_their_finite_differences():
    rng = np.random.default_rng(2)
    for w in (0.0, 0.4, -1.3):
        pose, u = rng.normal(size=3), np.array([0.7, w])
        errors = jacobian_errors(UNICYCLE, pose, u, dt=0.3)
        assert set(errors) == {"F_x", "F_v"} and max(errors.values()) < 1e-7, errors


@pytest.mark.parametrize(
    ("backend", "linearization"),
    [("python", "standard"), ("python", "fej"), ("python", "invariant"), ("numba", "standard")],
)
def test_a_unicycle_run_matches_the_literal_reference(backend, linearization):
    config = FilterConfig(motion=UNICYCLE, backend=backend, linearization=linearization)
    P0 = np.diag([1e-4, 1e-4, 1e-5])
    fast = EKFSLAM([0.0, 0.0, 0.1], P0, config)
    slow = LiteralEKFSLAM([0.0, 0.0, 0.1], P0, config)
    for event in events(seed=4):
        if event[0] == "predict":
            _, u, dt, t = event
            fast.predict_many(u.reshape(1, 2), np.array([dt]), np.array([t]), M=M)
            slow.predict(u, t=t, dt=dt, M=M)
        else:
            for f in (fast, slow):
                f.update(event[1], event[2], Q, event[3])
    assert fast.n_landmarks == 6 and fast.counts == slow.counts
    assert fast.counts.predictions == 120 and fast.counts.accepted > 200
    np.testing.assert_allclose(fast.mu, slow.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.Sigma, slow.cartesian_Sigma, rtol=0, atol=1e-9)


def test_a_batch_of_rates_is_as_many_single_predictions_with_their_dt():
    """predict_many through K (v, ω) with K durations equals K predict calls with the same dt
    and each step's R = V (M dt) Vᵀ."""
    rng = np.random.default_rng(7)
    us, dts = rng.uniform(-0.5, 0.8, (5, 2)), rng.uniform(0.05, 0.3, 5)
    config = FilterConfig(motion=UNICYCLE, backend="python")
    batch = EKFSLAM([1.0, -0.5, 0.3], np.eye(3) * 1e-4, config)
    batch.update(1, [2.0, 0.4], Q)
    one = EKFSLAM([1.0, -0.5, 0.3], np.eye(3) * 1e-4, config)
    one.update(1, [2.0, 0.4], Q)
    batch.predict_many(us, dts, np.cumsum(dts), M=M)
    for u, dt, t in zip(us, dts, np.cumsum(dts), strict=True):
        V = drive_control_jacobian(one.pose, u, dt)
        one.predict(u, V @ (M * dt) @ V.T, t, dt=dt)
    np.testing.assert_allclose(batch.mu, one.mu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(batch.Sigma, one.Sigma, rtol=0, atol=1e-12)


def test_a_control_of_the_wrong_size_or_a_model_without_dt_is_refused():
    f = EKFSLAM([0.0, 0.0, 0.0], None, replace(FilterConfig(), motion=UNICYCLE))
    with pytest.raises(ConfigError, match="us"):
        f.predict_many([[0.1, 0.0, 0.0]], [0.1], [0.1], M=M)
    with pytest.raises(ConfigError, match="M"):
        f.predict_many([[0.1, 0.0]], [0.1], [0.1], M=np.eye(3))
    with pytest.raises(ConfigError, match="u"):
        f.predict([0.1, 0.0, 0.0], np.eye(3) * 1e-4)
    old = MotionModel(f=lambda p, u: p, F_x=drive_jacobian, F_v=drive_control_jacobian, name="old")
    with pytest.raises(ConfigError, match=r"'old': f must take \(pose, u, dt\)"):
        FilterConfig(motion=old)
    assert RANGE_BEARING.size == 2 and UNICYCLE.control_size == 2
