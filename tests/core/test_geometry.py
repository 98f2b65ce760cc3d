"""ekfslam.geometry: wrap_angle, SE(2) compose / invert, transform_points."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam.geometry import compose, invert, rotation, transform_points, wrap_angle

PI = math.pi
EDGE_ANGLES = [
    0.0,
    PI,
    -PI,
    3 * PI,
    -3 * PI,
    2 * PI,
    -2 * PI,
    math.nextafter(PI, 0.0),
    math.nextafter(PI, 10.0),
    math.nextafter(-PI, 0.0),
    math.nextafter(-PI, -10.0),
    1e-300,
    -1e-300,
    1e6,
    -1e6,
    1e12 + 0.5,
]


def _congruent(a: float, w: float, tol: float) -> bool:
    """w differs from a by a whole number of turns (up to rounding that grows with |a|)."""
    turns = (a - w) / (2 * PI)
    return abs(turns - round(turns)) <= tol


@pytest.mark.parametrize("angle", EDGE_ANGLES)
def test_wrap_scalar_range_and_congruence(angle):
    w = wrap_angle(angle)
    assert isinstance(w, float)
    assert -PI <= w < PI
    assert _congruent(angle, w, tol=1e-15 * max(1.0, abs(angle)) + 1e-15)


@pytest.mark.parametrize(
    ("angle", "expected"),
    [(PI, -PI), (-PI, -PI), (3 * PI, -PI), (-3 * PI, -PI), (2 * PI, 0.0), (PI / 2, PI / 2)],
)
def test_wrap_exact_values(angle, expected):
    assert wrap_angle(angle) == expected
    assert wrap_angle(np.array([angle]))[0] == expected


def test_wrap_int_and_numpy_scalar():
    assert wrap_angle(7) == pytest.approx(7 - 2 * PI, abs=1e-15)
    assert isinstance(wrap_angle(np.float64(4.0)), float)
    assert wrap_angle(np.float64(4.0)) == pytest.approx(4.0 - 2 * PI, abs=1e-15)


def test_wrap_array_range_shape_and_agreement_with_scalar_path():
    rng = np.random.default_rng(0)
    angles = np.concatenate([EDGE_ANGLES, rng.uniform(-50, 50, 200)]).reshape(-1, 4)
    wrapped = wrap_angle(angles)
    assert wrapped.shape == angles.shape
    assert np.all(wrapped >= -PI) and np.all(wrapped < PI)
    for a, w in zip(angles.ravel(), wrapped.ravel(), strict=True):
        assert w == wrap_angle(float(a))
        assert _congruent(a, w, tol=1e-15 * max(1.0, abs(a)) + 1e-15)


def test_wrap_is_identity_inside_the_range():
    inside = np.linspace(-PI, PI, 1001)[:-1]
    np.testing.assert_array_equal(wrap_angle(inside), inside)


def _random_poses(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-5, 5, (n, 2)), rng.uniform(-PI, PI, n)])


def _assert_pose_close(a, b, atol=1e-12):
    np.testing.assert_allclose(a[:2], b[:2], rtol=0, atol=atol)
    assert abs(wrap_angle(float(a[2] - b[2]))) <= atol


def test_compose_with_inverse_is_identity():
    for a in _random_poses(200, 1):
        _assert_pose_close(compose(a, invert(a)), np.zeros(3))
        _assert_pose_close(compose(invert(a), a), np.zeros(3))
        _assert_pose_close(invert(invert(a)), a)


def test_compose_is_associative_and_wraps():
    poses = _random_poses(300, 2).reshape(100, 3, 3)
    for a, b, c in poses:
        _assert_pose_close(compose(compose(a, b), c), compose(a, compose(b, c)))
        assert -PI <= compose(a, b)[2] < PI
    assert compose([0.0, 0.0, 3.0], [0.0, 0.0, 1.0])[2] == pytest.approx(4.0 - 2 * PI)


def test_compose_and_invert_hand_computed():
    np.testing.assert_allclose(compose([1.0, 0.0, PI / 2], [1.0, 0.0, 0.0]), [1.0, 1.0, PI / 2])
    np.testing.assert_allclose(invert([1.0, 2.0, PI / 2]), [-2.0, 1.0, -PI / 2], atol=1e-15)


def test_transform_points_hand_computed_and_shapes():
    out = transform_points([1.0, 2.0, PI / 2], [[1.0, 0.0], [0.0, 1.0], [0.0, 0.0]])
    np.testing.assert_allclose(out, [[1.0, 3.0], [0.0, 2.0], [1.0, 2.0]], atol=1e-15)
    assert transform_points([0.0, 0.0, 0.0], [3.0, 4.0]).shape == (1, 2)
    assert transform_points([0.0, 0.0, 1.0], np.zeros((0, 2))).shape == (0, 2)


def test_transform_points_agrees_with_compose_and_inverts():
    rng = np.random.default_rng(3)
    for a, b in _random_poses(200, 4).reshape(100, 2, 3):
        np.testing.assert_allclose(transform_points(a, b[:2])[0], compose(a, b)[:2], atol=1e-12)
        pts = rng.uniform(-10, 10, (5, 2))
        back = transform_points(invert(a), transform_points(a, pts))
        np.testing.assert_allclose(back, pts, rtol=0, atol=1e-12)
        # a rigid transform keeps distances
        dist = np.linalg.norm(pts[1:] - pts[:-1], axis=1)
        moved = transform_points(a, pts)
        np.testing.assert_allclose(np.linalg.norm(moved[1:] - moved[:-1], axis=1), dist)


def test_rotation_is_proper_orthogonal():
    for t in np.linspace(-PI, PI, 13):
        Rt = rotation(float(t))
        np.testing.assert_allclose(Rt @ Rt.T, np.eye(2), atol=1e-15)
        assert np.linalg.det(Rt) == pytest.approx(1.0)
    np.testing.assert_allclose(rotation(PI / 2) @ [1.0, 0.0], [0.0, 1.0], atol=1e-15)
