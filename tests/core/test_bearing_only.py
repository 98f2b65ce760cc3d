"""A bearing-only sensor (a camera without depth), written here through the public API alone
(issue 37, item 2): z of one number, a landmark placed by delayed triangulation from two
sightings (`ekfslam.core.initialisation`), the filter in both backends matched to the literal
F_x reference, the Jacobians to finite differences, and the run consistent (NEES in its χ²
band over Monte Carlo seeds)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.filter.history import Outcome
from ekfslam.core.initialisation import Held, triangulated
from ekfslam.core.models import ODOMETRY, SensorModel
from ekfslam.errors import ConfigError
from ekfslam.geometry import wrap_angle
from ekfslam.teaching.finite_differences import central, jacobian_errors
from ekfslam.teaching.reference import LiteralEKFSLAM


def bearing(pose, landmark):
    """ẑ = (φ,): the landmark's bearing from the robot's heading (eq. 13 without the range)."""
    return np.array(
        (wrap_angle(math.atan2(landmark[1] - pose[1], landmark[0] - pose[0]) - pose[2]),)
    )


def bearing_jacobians(pose, landmark):
    """∂φ/∂pose (1, 3) and ∂φ/∂landmark (1, 2): eq. (14)'s second row."""
    dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
    q = dx * dx + dy * dy
    return np.array(((dy / q, -dx / q, -1.0),)), np.array(((-dy / q, dx / q),))


def bearing_innovation(z, z_hat):
    return np.array((wrap_angle(z[0] - z_hat[0]),))


def meet(pose_a, z_a, pose_b, z_b):
    """Where the rays of two bearings meet (2,); NaN when they are parallel or meet behind."""
    ca, sa = math.cos(pose_a[2] + z_a[0]), math.sin(pose_a[2] + z_a[0])
    cb, sb = math.cos(pose_b[2] + z_b[0]), math.sin(pose_b[2] + z_b[0])
    bx, by = pose_b[0] - pose_a[0], pose_b[1] - pose_a[1]
    det = cb * sa - ca * sb  # of [[ca, -cb], [sa, -sb]]
    if det == 0.0:
        return np.array((math.nan, math.nan))
    s, t = (cb * by - sb * bx) / det, (ca * by - sa * bx) / det
    if not (s > 0.0 and t > 0.0):
        return np.array((math.nan, math.nan))
    return np.array((pose_a[0] + s * ca, pose_a[1] + s * sa))


BEARING = SensorModel(
    h=bearing,
    H=bearing_jacobians,
    g=None,
    G=None,
    innovation=bearing_innovation,
    name="bearing",
    size=1,
    triangulate=meet,
)
SIGMA = 0.01  # rad, the bearing's noise
Q = np.array([[SIGMA**2]])
M = np.diag([2e-4, 1e-5, 2e-5])  # per second: the increments' noise
DT = 0.2
CHI2_1DOF_99 = 6.63
CONFIG = FilterConfig(sensor=BEARING, reinit_after=None, gate=CHI2_1DOF_99, backend="python")


def world(seed: int, steps: int = 150):
    """A robot driving a circle of 3 m among 8 landmarks, its odometry noisy, bearings of the
    landmarks within 70° of its heading (three at most a step): (true poses, landmarks, steps),
    each step (u, t, [(landmark id, z), ...])."""
    rng = np.random.default_rng(seed)
    angles = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    marks = np.column_stack((6.0 * np.cos(angles), 6.0 * np.sin(angles)))
    marks += rng.normal(0, 0.3, marks.shape)
    pose = np.array([3.0, 0.0, np.pi / 2])
    truth, drive = [], []
    C = np.linalg.cholesky(M * DT)
    for k in range(steps):
        u = np.array([0.5 * DT, 0.0, 0.5 / 3.0 * DT])
        pose = ODOMETRY.f(pose, u, DT)
        seen = [(j, bearing(pose, m)) for j, m in enumerate(marks)]
        seen = [(j, z) for j, z in seen if abs(z[0]) < np.radians(70)]
        sightings = [
            (seen[i][0], seen[i][1] + rng.normal(0, SIGMA, 1))
            for i in rng.permutation(len(seen))[:3]
        ]
        drive.append((u + C @ rng.normal(size=3), (k + 1) * DT, sightings))
        truth.append(pose.copy())
    return np.array(truth), marks, drive


def step(f, u, t, sightings):
    """One step into a filter: `EKFSLAM` by its public steps, the literal reference by its
    own (M per second: R = V (M dt) Vᵀ)."""
    if isinstance(f, LiteralEKFSLAM):
        f.predict(u, t=t, dt=DT, M=M)
    else:
        f.predict_many(u.reshape(1, 3), np.array([DT]), np.array([t]), M=M)
    for j, z in sightings:
        f.update(j, z, Q, t)


def test_the_sensors_jacobians_are_their_finite_differences():
    rng = np.random.default_rng(3)
    for _ in range(20):
        pose, landmark = rng.normal(size=3), rng.normal(0, 4, 2)
        errors = jacobian_errors(BEARING, pose, landmark, angles=(0,))
        assert set(errors) == {"H_r", "H_l"} and max(errors.values()) < 1e-7, errors


def test_the_triangulations_jacobians_are_its_finite_differences():
    """G_a = ∂m/∂pose_a, G_b = ∂m/∂pose_b and L = ∂m/∂(z_a, z_b), against central differences
    of the triangulated point."""
    a, b = np.array([0.0, 0.0, 0.3]), np.array([1.0, 0.4, 0.1])
    landmark = np.array([3.0, 2.5])
    z_a, z_b = bearing(a, landmark), bearing(b, landmark)
    placement, _ = triangulated(BEARING, Held(a, z_a, Q), Held(b, z_b, Q), 0.05)
    assert placement is not None
    np.testing.assert_allclose(placement.landmark, landmark, atol=1e-12)
    np.testing.assert_allclose(placement.G_a, central(lambda p: meet(p, z_a, b, z_b), a), atol=1e-7)
    np.testing.assert_allclose(placement.G_b, central(lambda p: meet(a, z_a, p, z_b), b), atol=1e-7)
    z = np.concatenate((z_a, z_b))
    np.testing.assert_allclose(
        placement.L, central(lambda v: meet(a, v[:1], b, v[1:]), z), atol=1e-6
    )
    assert placement.Q.shape == (2, 2)


def test_too_little_parallax_holds_the_first_sighting_and_disagreeing_ones_hold_the_later():
    a, landmark = np.array([0.0, 0.0, 0.0]), np.array([5.0, 0.0])
    near = np.array([0.05, 0.1, 0.0])  # a 2 cm baseline: the rays meet at ~1°
    z_a = bearing(a, landmark)
    assert triangulated(BEARING, Held(a, z_a, Q), Held(near, bearing(near, landmark), Q), 0.1) == (
        None,
        True,
    )
    away = np.array([0.0, 2.0, 0.0])  # a bearing pointing away: the rays do not meet ahead
    assert triangulated(BEARING, Held(a, z_a, Q), Held(away, np.array([1.0]), Q), 0.1) == (
        None,
        False,
    )


def test_a_landmark_is_deferred_then_placed_with_its_cross_covariance():
    f = EKFSLAM([0.0, 0.0, 0.0], np.diag([1e-3, 1e-3, 1e-4]), CONFIG)
    landmark = np.array([4.0, 3.0])
    assert f.update(7, bearing(f.pose, landmark), Q, 0.0) == Outcome.DEFERRED
    assert f.n_landmarks == 0
    f.predict_many([[1.5, 0.0, 0.0]], [1.0], [1.0], M=M)
    assert f.update(7, bearing(f.pose, landmark), Q, 1.0) == Outcome.INITIALISED
    np.testing.assert_allclose(f.landmark(7)[0], landmark, atol=1e-9)
    assert np.abs(f.Sigma[3:5, :3]).max() > 1e-5  # correlated with the pose
    assert np.all(np.linalg.eigvalsh(f.Sigma) > -1e-12)
    assert (f.counts.deferred, f.counts.initialised) == (1, 1)
    h = f.history()
    assert h.obs_z.shape == (2, 1) and h.obs_S.shape == (2, 1, 1)
    assert list(h.obs_outcome) == [Outcome.DEFERRED, Outcome.INITIALISED]


@pytest.mark.parametrize("backend", ["python", "numba"])
def test_a_bearing_only_run_matches_the_literal_reference(backend):
    config = replace(CONFIG, backend=backend)
    _, _, drive = world(seed=5, steps=150)
    P0 = np.diag([1e-4, 1e-4, 1e-5])
    fast = EKFSLAM([3.0, 0.0, np.pi / 2], P0, config)
    slow = LiteralEKFSLAM([3.0, 0.0, np.pi / 2], P0, config)
    for u, t, sightings in drive:
        for f in (fast, slow):
            step(f, u, t, sightings)
    assert fast.n_landmarks == slow.n_landmarks >= 4
    assert fast.counts == slow.counts and fast.counts.accepted > 100
    np.testing.assert_allclose(fast.mu, slow.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.Sigma, slow.cartesian_Sigma, rtol=0, atol=1e-9)


def test_the_bearing_only_run_is_consistent_over_monte_carlo_seeds():
    """The pose's NEES averaged over 40 seeds, N ε̄ ~ χ²(3 N), inside its two-sided 99% band on
    at least 90% of the steps; the landmarks' mean NEES at the end within a factor 2 of its 2
    degrees of freedom."""
    runs, steps = 40, 150
    nees = np.zeros((runs, steps))
    landmark_nees = []
    for seed in range(runs):
        truth, marks, drive = world(seed, steps)
        f = EKFSLAM([3.0, 0.0, np.pi / 2], None, CONFIG)
        for k, (u, t, sightings) in enumerate(drive):
            step(f, u, t, sightings)
            e = f.pose - truth[k]
            e[2] = wrap_angle(e[2])
            nees[seed, k] = e @ np.linalg.solve(f.pose_covariance, e)
        for i in f.landmark_ids:
            m, P = f.landmark(i)
            e = m - marks[i]
            landmark_nees.append(e @ np.linalg.solve(P, e))
    mean = nees.mean(axis=0)
    lo, hi = chi2.ppf([0.005, 0.995], 3 * runs) / runs
    inside = np.mean((mean >= lo) & (mean <= hi))
    assert inside >= 0.9, (inside, mean.min(), mean.max(), lo, hi)
    # the map: the standard EKF's own overconfidence (Bailey et al., "Consistency of the EKF-SLAM
    # algorithm", IROS 2006) shows there first; measured 2.8 for 2 degrees of freedom over 30
    # seeds (a placement spread of 0.2 instead of `max_spread`'s 0.1 gave 8-11 with a heading
    # noise of 1e-4 rad²/s): held within a factor 2
    assert len(landmark_nees) >= 6 * runs
    assert 1.0 <= np.mean(landmark_nees) <= 4.0, np.mean(landmark_nees)


def test_a_measurement_of_the_wrong_size_or_a_sensor_without_a_placement_is_refused():
    f = EKFSLAM([0.0, 0.0, 0.0], None, CONFIG)
    with pytest.raises(ConfigError, match="z"):
        f.update(1, [0.1, 0.2], Q)
    with pytest.raises(ConfigError, match="Q"):
        f.update(1, [0.1], np.eye(2))
    with pytest.raises(ConfigError, match="reinit_after=None"):
        FilterConfig(sensor=BEARING)
    with pytest.raises(ValueError, match="triangulate"):
        SensorModel(bearing, bearing_jacobians, None, None, bearing_innovation, "no way", 1)
