"""ekfslam.teaching.derivations: the sympy forms, the seed's eq. (14), the lifts of eqs. (7)-(9),
LaTeX."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

from ekfslam.core.models import DegenerateGeometry
from ekfslam.teaching import derivations as d

# --- the derived models against the seed's printed equations ------------------------------------


def test_derived_eq14_equals_the_seed_printed_matrix():
    diff = d.seed_observation_jacobian_difference()
    assert diff.shape == (2, 5)
    assert diff.is_zero_matrix
    assert d.derived_observation_jacobian().shape == (2, 5)


def test_the_eq14_comparison_can_find_a_difference():
    # Flip the sign of the -q entry (the ∂φ/∂θ term): the comparison must say where.
    wrong = sp.Matrix(d.seed_observation_jacobian())
    wrong[1, 2] = 1
    diff = d.observation_jacobian_difference(sp.ImmutableMatrix(wrong))
    assert diff[1, 2] == -2
    assert sum(1 for entry in diff if entry != 0) == 1


def test_derived_eq14_at_a_hand_computed_point():
    # δ = (3, 4): √q = 5, q = 25
    H = d.derived_observation_jacobian().subs({d.delta_x: 3, d.delta_y: 4})
    fifth, q = sp.Rational(1, 5), sp.Rational(1, 25)
    expected = sp.Matrix(
        [[-3 * fifth, -4 * fifth, 0, 3 * fifth, 4 * fifth], [4 * q, -3 * q, -1, -4 * q, 3 * q]]
    )
    assert H == expected


def test_motion_jacobians_equal_eqs_5_and_7_as_printed():
    model = d.motion_model()
    s, c = sp.sin(d.theta), sp.cos(d.theta)
    eq7 = sp.Matrix([[1, 0, -d.du_x * s - d.du_y * c], [0, 1, d.du_x * c - d.du_y * s], [0, 0, 1]])
    eq5 = sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    assert sp.simplify(model.jacobian_pose - eq7).is_zero_matrix
    assert sp.simplify(model.jacobian_input - eq5).is_zero_matrix
    assert model.equation == "(6)"


def test_inverse_observation_jacobians_are_the_hand_derivatives():
    model = d.inverse_observation_model()
    a = d.phi + d.theta
    assert sp.simplify(
        model.jacobian_pose[:, 2] - sp.Matrix([-d.r * sp.sin(a), d.r * sp.cos(a)])
    ).is_zero_matrix
    assert sp.simplify(
        model.jacobian_input
        - sp.Matrix([[sp.cos(a), -d.r * sp.sin(a)], [sp.sin(a), d.r * sp.cos(a)]])
    ).is_zero_matrix


def test_observation_model_uses_atan2_not_arctan():
    bearing = d.observation_model().value[1]
    assert bearing.has(sp.atan2)
    assert not bearing.has(sp.atan)
    assert d.seed_bearing_expr().has(sp.atan)


def test_derivations_are_cached():
    assert d.motion_model() is d.motion_model()
    assert d.numeric_models() is d.numeric_models()
    assert d.seed_lift_shapes(2) is d.seed_lift_shapes(2)


def test_import_derives_nothing():
    code = (
        "import ekfslam.teaching.derivations as d\n"
        "assert d.motion_model.cache_info().currsize == 0\n"
        "assert d.observation_model.cache_info().currsize == 0\n"
        "assert d.numeric_models.cache_info().currsize == 0\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


# --- arctan(δy/δx) against atan2 ----------------------------------------------------------------


@pytest.mark.parametrize(
    ("dx", "dy", "theta", "seed", "right"),
    [
        (1.0, 1.0, 0.0, math.pi / 4, math.pi / 4),
        (-1.0, 1.0, 0.0, -math.pi / 4, 3 * math.pi / 4),
        (-1.0, -1.0, 0.0, math.pi / 4, -3 * math.pi / 4),
        (1.0, -1.0, 0.0, -math.pi / 4, -math.pi / 4),
        (0.0, 1.0, 0.0, math.pi / 2, math.pi / 2),
        (-1.0, -1.0, math.pi / 2, -math.pi / 4, 3 * math.pi / 4),
    ],
)
def test_compare_bearings(dx, dy, theta, seed, right):
    cmp = d.compare_bearings(dx, dy, theta)
    assert cmp.seed_arctan == pytest.approx(seed, abs=1e-15)
    assert cmp.atan2 == pytest.approx(right, abs=1e-15)
    expected_gap = math.pi if dx < 0 else 0.0
    assert abs(cmp.difference) == pytest.approx(expected_gap, abs=1e-15)
    assert -math.pi <= cmp.difference < math.pi


def test_compare_bearings_rejects_the_robot_position():
    with pytest.raises(DegenerateGeometry):
        d.compare_bearings(0.0, 0.0)


# --- the lifts of eqs. (7), (8), (9) and (14) ---------------------------------------------------


@pytest.mark.parametrize("n", [1, 2, 5])
def test_seed_lifts_with_a_3x3_inner_matrix_are_undefined(n):
    shapes = d.seed_lift_shapes(n)
    size = 2 * n + 3
    assert shapes.state_size == size
    assert shapes.F_x == (3, size)
    assert shapes.F_x_j == (5, size)
    # eqs. (7) and (9) as printed: F_x (3x3) F_xᵀ does not multiply
    assert shapes.seed_G is None and "mismatch" in shapes.seed_G_error
    assert shapes.seed_R is None and "mismatch" in shapes.seed_R_error
    # the product is only defined for a full-size inner matrix, and then it is 3x3, not full size
    assert shapes.pose_block_of_full == (3, 3)
    # eq. (14) multiplies fine
    assert shapes.seed_H == (2, size)
    # the lifts that work
    assert shapes.lifted_R == (size, size) and shapes.lifted_R_is_padded
    assert shapes.lifted_G == (size, size) and shapes.lifted_G_is_block_diagonal
    assert shapes.transposed_G_drops_landmarks


def test_seed_lifts_with_no_landmark_are_the_identity_lift():
    shapes = d.seed_lift_shapes(0)
    assert shapes.F_x == (3, 3) and shapes.F_x_j is None and shapes.seed_H is None
    assert shapes.seed_G == shapes.seed_R == shapes.lifted_G == shapes.lifted_R == (3, 3)
    assert shapes.seed_G_error == shapes.seed_R_error == ""
    assert not shapes.transposed_G_drops_landmarks


def test_shape_error_directly_in_sympy():
    F = d.lift_matrix(2)
    R = sp.Matrix(3, 3, sp.symbols("a0:9"))
    with pytest.raises(sp.ShapeError):
        F * R * F.T
    assert (F.T * R * F).shape == (7, 7)
    assert (F * sp.eye(7) * F.T).shape == (3, 3)


def test_lifted_motion_jacobian_is_G_then_identity():
    G_full = d.lifted_motion_jacobian(2)
    assert G_full.shape == (7, 7)
    assert G_full[:3, :3] == d.motion_model().jacobian_pose
    assert G_full[3:, 3:] == sp.eye(4)
    assert G_full[:3, 3:].is_zero_matrix and G_full[3:, :3].is_zero_matrix


def test_lifted_observation_jacobian_places_the_landmark_columns():
    H = d.lifted_observation_jacobian(3, 1)
    block = d.derived_observation_jacobian()
    assert H.shape == (2, 9)
    assert H[:, :3] == block[:, :3]
    assert H[:, 5:7] == block[:, 3:]
    assert H[:, 3:5].is_zero_matrix and H[:, 7:].is_zero_matrix


@pytest.mark.parametrize("n", [0, 1, 2, 4])
def test_numeric_lift_matrix(n):
    F = d.lift_matrix_numeric(n)
    assert F.shape == (3, 3 + 2 * n)
    np.testing.assert_array_equal(F[:, :3], np.eye(3))
    assert not F[:, 3:].any()
    mu = np.arange(3.0 + 2 * n)
    np.testing.assert_array_equal(F @ mu, [0.0, 1.0, 2.0])
    np.testing.assert_array_equal(np.asarray(d.lift_matrix(n), dtype=float), F)


@pytest.mark.parametrize(("n", "j"), [(1, 0), (3, 0), (3, 2), (5, 3)])
def test_numeric_landmark_lift_matrix(n, j):
    F = d.landmark_lift_matrix_numeric(n, j)
    assert F.shape == (5, 3 + 2 * n)
    mu = np.arange(3.0 + 2 * n)
    np.testing.assert_array_equal(F @ mu, [0, 1, 2, 3 + 2 * j, 4 + 2 * j])
    np.testing.assert_array_equal(F.sum(axis=1), np.ones(5))  # one 1 per row, zeros elsewhere
    assert np.count_nonzero(F) == 5
    np.testing.assert_array_equal(np.asarray(d.landmark_lift_matrix(n, j), dtype=float), F)


@pytest.mark.parametrize(("n", "j"), [(3, 3), (3, -1), (0, 0), (-1, None)])
def test_lifts_reject_bad_slots(n, j):
    with pytest.raises(ValueError, match="landmark"):
        if j is None:
            d.lift_matrix_numeric(n)
        else:
            d.landmark_lift_matrix_numeric(n, j)


# --- LaTeX --------------------------------------------------------------------------------------


def test_latex_of_the_models():
    f, G, V = d.motion_model().latex()
    assert G.startswith("G = ") and r"\Delta u_x" in G and r"\sin" in G
    assert f.startswith("f = ") and r"\Delta \theta" in f
    assert V.startswith("V = ") and r"\cos" in V
    z_hat, H_pose, H_landmark = d.observation_model().latex()
    assert r"\operatorname{atan}_{2}" in z_hat
    assert r"\mu_{j,x}" in H_pose and r"\mu_{j,y}" in H_landmark
    m, G_pose, G_z = d.inverse_observation_model().latex()
    assert r"\phi + \theta" in m and G_pose.startswith("G_{pose} = ") and G_z.startswith("G_{z}")


def test_latex_of_the_seed_forms():
    eq14 = d.seed_observation_jacobian_latex()
    assert eq14.startswith(r"H = \frac{1}{q}") and r"\sqrt{q}" in eq14 and r"\delta_x" in eq14
    assert r"\operatorname{atan}{\left(\frac{\delta_y}{\delta_x}" in d.latex(d.seed_bearing_expr())
    assert d.latex(d.observation_noise_expr(), "Q").startswith("Q = ")
    assert r"\sigma_r^{2}" in d.latex(d.observation_noise_expr())
