"""The numeric models of ekfslam.core.models against sympy, finite differences and plain geometry.

Every function is checked on the same sample of random states (N_CASES > 100): bearings in all
four quadrants, world-frame offsets in all four quadrants, and headings right next to ±π, where
both the motion heading and the bearing wrap.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam.core import models
from ekfslam.geometry import compose, invert, transform_points, wrap_angle
from ekfslam.teaching.derivations import compare_bearings, numeric_models

N_CASES = 124
HEADINGS_NEAR_PI = (math.pi - 1e-3, -math.pi + 1e-3, -math.pi)
H = 1e-6  # finite-difference step: truncation ~h² and rounding ~1e-16/h both far below 1e-6


@pytest.fixture(scope="module")
def cases() -> dict[str, np.ndarray]:
    """Poses, controls, landmarks and the matching observations z = (r, φ)."""
    rng = np.random.default_rng(20240611)
    poses = np.column_stack(
        [
            rng.uniform(-5, 5, N_CASES),
            rng.uniform(-5, 5, N_CASES),
            rng.uniform(-np.pi, np.pi, N_CASES),
        ]
    )
    poses[: len(HEADINGS_NEAR_PI), 2] = HEADINGS_NEAR_PI
    # bearings stratified over the four quadrants, kept off the axes
    quadrant = np.arange(N_CASES) % 4
    phi = -np.pi + (quadrant + rng.uniform(0.05, 0.95, N_CASES)) * (np.pi / 2)
    rng_ = rng.uniform(0.3, 8.0, N_CASES)
    world = poses[:, 2] + phi
    landmarks = poses[:, :2] + rng_[:, None] * np.column_stack([np.cos(world), np.sin(world)])
    controls = rng.uniform(-0.5, 0.5, (N_CASES, 3))
    return {
        "poses": poses,
        "controls": controls,
        "landmarks": landmarks,
        "z": np.column_stack([rng_, phi]),
    }


def _quadrants(xs: np.ndarray, ys: np.ndarray) -> set[tuple[bool, bool]]:
    return set(zip((xs > 0).tolist(), (ys > 0).tolist(), strict=True))


def assert_angles_close(actual: float, expected: float, atol: float, msg: str = "") -> None:
    assert abs(wrap_angle(float(actual) - float(expected))) <= atol, (
        f"{msg}: {actual} vs {expected}"
    )


def central_difference(fn, args: list[np.ndarray], which: int, angle_rows: tuple[int, ...]):
    """∂fn/∂args[which] by central differences; rows in `angle_rows` are differenced wrapped."""
    base = np.asarray(args[which], dtype=float)
    columns = []
    for k in range(base.size):
        step = np.zeros_like(base)
        step[k] = H
        plus = list(args)
        minus = list(args)
        plus[which] = base + step
        minus[which] = base - step
        diff = np.asarray(fn(*plus)) - np.asarray(fn(*minus))
        for row in angle_rows:
            diff[row] = wrap_angle(float(diff[row]))
        columns.append(diff / (2 * H))
    return np.column_stack(columns)


def test_sample_covers_all_quadrants_and_headings_near_pi(cases):
    phi = cases["z"][:, 1]
    assert _quadrants(np.cos(phi), np.sin(phi)) == {(a, b) for a in (1, 0) for b in (1, 0)}
    offsets = cases["landmarks"] - cases["poses"][:, :2]
    assert len(_quadrants(offsets[:, 0], offsets[:, 1])) == 4
    for heading in HEADINGS_NEAR_PI:
        assert np.any(cases["poses"][:, 2] == heading)
    assert len(phi) >= 100


# --- (a) against the lambdified sympy derivations, 1e-12 ----------------------------------------


def test_motion_and_its_jacobians_match_sympy(cases):
    twin = numeric_models()
    for i, (p, u) in enumerate(zip(cases["poses"], cases["controls"], strict=True)):
        got, want = models.motion(p, u), twin.motion(p, u)
        assert got.shape == want.shape == (3,)
        np.testing.assert_allclose(got[:2], want[:2], rtol=0, atol=1e-12, err_msg=f"case {i}")
        assert_angles_close(got[2], want[2], 1e-12, f"case {i}")
        assert -np.pi <= got[2] < np.pi
        for name, args in (("motion_jacobian", (p, u)), ("motion_control_jacobian", (p,))):
            got_J, want_J = getattr(models, name)(*args), getattr(twin, name)(*args)
            assert got_J.shape == want_J.shape == (3, 3)
            np.testing.assert_allclose(got_J, want_J, rtol=0, atol=1e-12, err_msg=f"{name} {i}")


def test_observation_and_its_jacobians_match_sympy(cases):
    twin = numeric_models()
    for i, (p, m) in enumerate(zip(cases["poses"], cases["landmarks"], strict=True)):
        got, want = models.observation(p, m), twin.observation(p, m)
        assert got.shape == want.shape == (2,)
        np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-12, err_msg=f"case {i}")
        assert_angles_close(got[1], want[1], 1e-12, f"case {i}")
        assert_blocks_equal(
            models.observation_jacobians(p, m), twin.observation_jacobians(p, m), f"case {i}"
        )


def assert_blocks_equal(got, want, message: str) -> None:
    """The (2x3 pose, 2x2 other) Jacobian blocks agree with the sympy ones to 1e-12."""
    for got_J, want_J, shape in zip(got, want, ((2, 3), (2, 2)), strict=True):
        assert got_J.shape == want_J.shape == shape
        np.testing.assert_allclose(got_J, want_J, rtol=0, atol=1e-12, err_msg=message)


def test_inverse_observation_and_its_jacobians_match_sympy(cases):
    twin = numeric_models()
    for i, (p, z) in enumerate(zip(cases["poses"], cases["z"], strict=True)):
        got, want = models.inverse_observation(p, z), twin.inverse_observation(p, z)
        assert got.shape == want.shape == (2,)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12, err_msg=f"case {i}")
        assert_blocks_equal(
            models.inverse_observation_jacobians(p, z),
            twin.inverse_observation_jacobians(p, z),
            f"case {i}",
        )


def test_noise_models_match_sympy(cases):
    twin = numeric_models()
    rng = np.random.default_rng(7)
    for i, p in enumerate(cases["poses"]):
        A = rng.normal(size=(3, 3))
        M = A @ A.T + 0.1 * np.eye(3)
        np.testing.assert_allclose(
            models.motion_noise(p, M), twin.motion_noise(p, M), rtol=0, atol=1e-12, err_msg=f"{i}"
        )
    for s_r, s_phi in rng.uniform(1e-3, 1.0, (N_CASES, 2)):
        np.testing.assert_allclose(
            models.observation_noise(s_r, s_phi), twin.observation_noise(s_r, s_phi), atol=1e-15
        )


# --- (b) against central finite differences, 1e-6 ------------------------------------------------


def test_motion_jacobians_match_finite_differences(cases):
    for i, (p, u) in enumerate(zip(cases["poses"], cases["controls"], strict=True)):
        G = central_difference(models.motion, [p, u], 0, angle_rows=(2,))
        V = central_difference(models.motion, [p, u], 1, angle_rows=(2,))
        np.testing.assert_allclose(models.motion_jacobian(p, u), G, atol=1e-6, err_msg=f"G {i}")
        np.testing.assert_allclose(models.motion_control_jacobian(p), V, atol=1e-6, err_msg=f"{i}")


def test_observation_jacobians_match_finite_differences(cases):
    for i, (p, m) in enumerate(zip(cases["poses"], cases["landmarks"], strict=True)):
        H_pose, H_landmark = models.observation_jacobians(p, m)
        fd_pose = central_difference(models.observation, [p, m], 0, angle_rows=(1,))
        fd_landmark = central_difference(models.observation, [p, m], 1, angle_rows=(1,))
        np.testing.assert_allclose(H_pose, fd_pose, atol=1e-6, err_msg=f"H_pose {i}")
        np.testing.assert_allclose(H_landmark, fd_landmark, atol=1e-6, err_msg=f"H_landmark {i}")


def test_inverse_observation_jacobians_match_finite_differences(cases):
    for i, (p, z) in enumerate(zip(cases["poses"], cases["z"], strict=True)):
        G_pose, G_z = models.inverse_observation_jacobians(p, z)
        fd_pose = central_difference(models.inverse_observation, [p, z], 0, angle_rows=())
        fd_z = central_difference(models.inverse_observation, [p, z], 1, angle_rows=())
        np.testing.assert_allclose(G_pose, fd_pose, atol=1e-6, err_msg=f"G_pose {i}")
        np.testing.assert_allclose(G_z, fd_z, atol=1e-6, err_msg=f"G_z {i}")


def test_wrapping_in_finite_differences_matters_at_the_seam():
    # Without wrapping, the bearing's difference across the ±π seam is ~2π, not ~2h.
    p = np.array([0.0, 0.0, 0.0])
    m = np.array([-2.0, 0.0])  # straight behind: bearing exactly on the seam
    step = np.array([0.0, H])
    raw_plus = models.observation(p, m + step)[1]
    raw_minus = models.observation(p, m - step)[1]
    assert abs(raw_plus - raw_minus) > 6.0
    fd = central_difference(models.observation, [p, m], 1, angle_rows=(1,))
    np.testing.assert_allclose(fd[1], [0.0, -0.5], atol=1e-6)  # d(atan2)/d(my) = dx / q


# --- against plain SE(2) geometry ---------------------------------------------------------------


def test_models_agree_with_se2_geometry(cases):
    for i, (p, u, m) in enumerate(
        zip(cases["poses"], cases["controls"], cases["landmarks"], strict=True)
    ):
        # eq. (6) is composition with the body-frame increment
        np.testing.assert_allclose(models.motion(p, u)[:2], compose(p, u)[:2], atol=1e-12)
        assert_angles_close(models.motion(p, u)[2], compose(p, u)[2], 1e-12, f"case {i}")
        # eq. (13): range and bearing of the landmark expressed in the robot frame
        local = transform_points(invert(p), m)[0]
        z = models.observation(p, m)
        assert z[0] == pytest.approx(math.hypot(*local), abs=1e-12)
        assert_angles_close(z[1], math.atan2(local[1], local[0]), 1e-12, f"case {i}")


def test_hand_computed_values():
    z = models.observation([1.0, 2.0, math.pi / 2], [4.0, 6.0])  # δ = (3, 4)
    assert z[0] == pytest.approx(5.0, abs=1e-15)
    assert z[1] == pytest.approx(math.atan2(4, 3) - math.pi / 2, abs=1e-15)
    H_pose, H_landmark = models.observation_jacobians([1.0, 2.0, 0.3], [4.0, 6.0])
    np.testing.assert_allclose(H_pose, [[-0.6, -0.8, 0], [0.16, -0.12, -1]], atol=1e-15)
    np.testing.assert_allclose(H_landmark, [[0.6, 0.8], [-0.16, 0.12]], atol=1e-15)
    np.testing.assert_allclose(
        models.motion([1.0, 2.0, math.pi / 2], [0.5, 0.1, 0.2]), [0.9, 2.5, math.pi / 2 + 0.2]
    )


# --- round trips, arctan vs atan2, degenerate geometry, noise ------------------------------------


def test_observation_inverts_inverse_observation(cases):
    for i, (p, z, m) in enumerate(zip(cases["poses"], cases["z"], cases["landmarks"], strict=True)):
        back = models.observation(p, models.inverse_observation(p, z))
        assert back[0] == pytest.approx(z[0], rel=1e-12), f"case {i}"
        assert_angles_close(back[1], z[1], 1e-12, f"case {i}")
        np.testing.assert_allclose(
            models.inverse_observation(p, models.observation(p, m)), m, atol=1e-12
        )


def test_atan2_differs_from_the_seed_arctan_by_pi_when_dx_is_negative(cases):
    behind = ahead = 0
    for p, m in zip(cases["poses"], cases["landmarks"], strict=True):
        dx, dy = m - p[:2]
        cmp = compare_bearings(dx, dy, p[2])
        assert_angles_close(models.observation(p, m)[1], cmp.atan2, 1e-12)
        if dx < 0:
            behind += 1
            assert abs(abs(cmp.difference) - math.pi) < 1e-12
            assert abs(wrap_angle(models.observation(p, m)[1] - cmp.seed_arctan)) > 3.14
        else:
            ahead += 1
            assert abs(cmp.difference) < 1e-12
    assert behind > 20 and ahead > 20
    # the landmark up and to the left of a robot at the origin facing +x: 135°, not -45°
    cmp = compare_bearings(-1.0, 1.0)
    assert cmp.atan2 == pytest.approx(3 * math.pi / 4)
    assert cmp.seed_arctan == pytest.approx(-math.pi / 4)
    assert models.observation([0.0, 0.0, 0.0], [-1.0, 1.0])[1] == pytest.approx(3 * math.pi / 4)


@pytest.mark.parametrize("offset", [0.0, 5e-7])
@pytest.mark.parametrize("fn", ["observation", "observation_jacobians"])
def test_landmark_on_the_robot_is_degenerate(fn, offset):
    pose = np.array([1.5, -2.0, 0.4])
    landmark = pose[:2] + offset
    with pytest.raises(models.DegenerateGeometry, match="sits on the robot"):
        getattr(models, fn)(pose, landmark)
    with pytest.raises(models.DegenerateGeometry):
        getattr(numeric_models(), fn)(pose, landmark)


def test_landmark_just_off_the_robot_is_fine():
    z = models.observation([1.5, -2.0, 0.0], [1.5 + 1e-5, -2.0])
    assert z[0] == pytest.approx(1e-5)
    assert z[1] == pytest.approx(0.0)


def test_motion_noise_is_V_M_Vt_and_symmetric(cases):
    rng = np.random.default_rng(3)
    for p in cases["poses"]:
        A = rng.normal(size=(3, 3))
        M = A @ A.T + 0.01 * np.eye(3)
        R = models.motion_noise(p, M)
        V = models.motion_control_jacobian(p)
        np.testing.assert_allclose(R, V @ M @ V.T, rtol=0, atol=1e-12)
        assert np.array_equal(R, R.T)
        # V is a rotation, so R has the eigenvalues of M
        np.testing.assert_allclose(np.linalg.eigvalsh(R), np.linalg.eigvalsh(M), atol=1e-12)
    # facing +y, body-forward variance becomes world-y variance
    R = models.motion_noise([0.0, 0.0, math.pi / 2], np.diag([4.0, 1.0, 0.25]))
    np.testing.assert_allclose(R, np.diag([1.0, 4.0, 0.25]), atol=1e-15)


def test_observation_noise_is_diagonal_of_variances():
    np.testing.assert_allclose(
        models.observation_noise(0.1, 0.02), [[0.01, 0.0], [0.0, 0.0004]], atol=1e-18
    )
