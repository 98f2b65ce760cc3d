"""Another sensor, swapped in without editing any filter, association or compiled file (issue 24).

A camera mounted off the robot's centre, `OFFSET` m forward and to the left, measuring range and
bearing from where it sits: its model is stated here, as a `SensorModel` made by a factory (its
mounting is a parameter the functions close over), and handed to `FilterConfig`. The filter, in
Python and compiled, must then agree with the literal F_x reference on it, and the association
must predict with it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam.core.association import AssociationConfig
from ekfslam.core.filter.associating import AssociatingFilter
from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.models import RANGE_BEARING, SensorModel, innovation, motion
from ekfslam.teaching.finite_differences import central
from ekfslam.teaching.reference import LiteralEKFSLAM

OFFSET = (0.12, -0.05)  # m: forward, left


def offset_camera(forward: float, left: float) -> SensorModel:
    """Range and bearing of a landmark from a camera at (forward, left) in the robot's frame."""

    def mount(pose):
        c, s = math.cos(pose[2]), math.sin(pose[2])
        return pose[0] + c * forward - s * left, pose[1] + s * forward + c * left

    def h(pose, landmark):
        x, y = mount(pose)
        dx, dy = landmark[0] - x, landmark[1] - y
        return np.array((math.hypot(dx, dy), math.atan2(dy, dx) - pose[2]))

    def H(pose, landmark):
        x, y = mount(pose)
        dx, dy = landmark[0] - x, landmark[1] - y
        q = dx * dx + dy * dy
        r = math.sqrt(q)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        turn = (s * forward + c * left, -c * forward + s * left)  # ∂δ/∂θ
        H_l = np.array(((dx / r, dy / r), (-dy / q, dx / q)))  # ∂z/∂δ
        H_r = np.array(
            (
                (-dx / r, -dy / r, H_l[0, 0] * turn[0] + H_l[0, 1] * turn[1]),
                (dy / q, -dx / q, H_l[1, 0] * turn[0] + H_l[1, 1] * turn[1] - 1.0),
            )
        )
        return H_r, H_l

    def g(pose, z):
        x, y = mount(pose)
        angle = pose[2] + z[1]
        return np.array((x + z[0] * math.cos(angle), y + z[0] * math.sin(angle)))

    def G(pose, z):
        c, s = math.cos(pose[2]), math.sin(pose[2])
        angle = pose[2] + z[1]
        ca, sa = math.cos(angle), math.sin(angle)
        G_r = np.array(
            (
                (1.0, 0.0, -s * forward - c * left - z[0] * sa),
                (0.0, 1.0, c * forward - s * left + z[0] * ca),
            )
        )
        G_z = np.array(((ca, -z[0] * sa), (sa, z[0] * ca)))
        return G_r, G_z

    return SensorModel(h=h, H=H, g=g, G=G, innovation=innovation, name="offset camera")


CAMERA = offset_camera(*OFFSET)


@pytest.mark.parametrize("seed", range(5))
def test_the_offset_cameras_jacobians_are_its_finite_differences(seed):
    rng = np.random.default_rng(seed)
    pose, landmark = rng.normal(0, 1, 3), rng.normal(0, 2, 2) + 3.0
    H_r, H_l = CAMERA.H(pose, landmark)
    np.testing.assert_allclose(H_r, central(lambda p: CAMERA.h(p, landmark), pose), atol=1e-7)
    np.testing.assert_allclose(H_l, central(lambda m: CAMERA.h(pose, m), landmark), atol=1e-7)
    z = CAMERA.h(pose, landmark)
    np.testing.assert_allclose(CAMERA.g(pose, z), landmark, atol=1e-12)
    G_r, G_z = CAMERA.G(pose, z)
    np.testing.assert_allclose(G_r, central(lambda p: CAMERA.g(p, z), pose), atol=1e-7)
    np.testing.assert_allclose(G_z, central(lambda v: CAMERA.g(pose, v), z), atol=1e-7)


def camera_run(rng, steps: int, n: int):
    """Events of a robot wandering among n landmarks, seen through the offset camera."""
    landmarks = rng.uniform(-2.5, 2.5, size=(n, 2))
    pose = np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi)])
    M = np.diag([0.01, 0.005, 0.01]) ** 2
    Q = np.diag([0.05, 0.03]) ** 2
    for _ in range(steps):
        u = np.array([rng.uniform(0.0, 0.1), rng.uniform(-0.03, 0.03), rng.uniform(-0.3, 0.3)])
        if np.hypot(*pose[:2]) > 2.5:
            u[2] = 0.6
        pose = motion(pose, u + rng.multivariate_normal(np.zeros(3), M))
        yield ("predict", u, M)
        for k in range(n):
            z = CAMERA.h(pose, landmarks[k])
            if z[0] > 3.0 or rng.random() < 0.5:
                continue
            z = z + rng.normal(0, [0.05, 0.03])
            z[1] = (z[1] + math.pi) % (2 * math.pi) - math.pi
            yield ("update", k, z, Q)


@pytest.mark.parametrize("backend", ["python", "numba"])
@pytest.mark.parametrize(
    ("linearization", "iterations"),
    [("standard", 1), ("fej", 1), ("invariant", 1), ("standard", 3)],
)
def test_the_filter_matches_the_literal_reference_on_another_sensor(
    linearization, iterations, backend
):
    config = FilterConfig(
        sensor=CAMERA, linearization=linearization, iterations=iterations, backend=backend
    )
    pose, P0 = [0.1, -0.2, 0.3], np.diag([1e-4, 1e-4, 1e-5])
    fast, slow = EKFSLAM(pose, P0, config), LiteralEKFSLAM(pose, P0, config)
    outcomes = []
    for event in camera_run(np.random.default_rng(4), 250, 8):
        for f in (fast, slow):
            if event[0] == "predict":
                f.predict(event[1], event[2])
            else:
                outcomes.append(f.update(*event[1:]))
    assert outcomes[0::2] == outcomes[1::2]
    assert fast.counts.accepted > 100 and fast.n_landmarks >= 5
    np.testing.assert_allclose(fast.mu, slow.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.Sigma, slow.cartesian_Sigma, rtol=0, atol=1e-9)


def test_the_sensor_changes_the_filter():
    """The same sightings through the seed's camera put the landmarks elsewhere: the offset
    camera's model is the one in use."""
    events = list(camera_run(np.random.default_rng(5), 40, 5))
    maps = []
    for sensor in (CAMERA, RANGE_BEARING):
        f = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(sensor=sensor))
        for event in events:
            if event[0] == "predict":
                f.predict(event[1], event[2])
            else:
                f.update(*event[1:])
        maps.append(f.mu[3:])
    assert np.abs(maps[0] - maps[1]).max() > 0.05  # about the 0.13 m offset


@pytest.mark.parametrize("backend", ["python", "numba"])
def test_the_association_predicts_through_the_swapped_sensor(backend):
    config = FilterConfig(sensor=CAMERA, backend=backend)
    f = EKFSLAM([0.0, 0.0, 0.0], np.diag([0.01, 0.01, 0.004]), config)
    marks = np.array([[2.0, 0.5], [1.5, -1.0], [-1.0, 2.0]])
    Q = np.diag([0.05, 0.03]) ** 2
    for j, m in enumerate(marks):
        f.update(j, CAMERA.h(np.zeros(3), m), Q)
    f.predict([0.1, 0.0, 0.05], np.diag([1e-3, 1e-3, 4e-3]))
    a = AssociatingFilter(f, AssociationConfig(method="jcbb"))
    zs = np.array([CAMERA.h(f.pose, m) for m in marks[[2, 0]]])
    nu, P = a.predicted(zs)  # written out with the whole H, through the sensor model
    got = f.predictions(zs, Q)
    np.testing.assert_allclose(got.nu, nu, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.P, P, rtol=1e-9, atol=1e-15)
    assert a.decide(zs, Q) == [2, 0]
    assert f.nearest(zs, Q, 9.21)[0] == [2, 0]
