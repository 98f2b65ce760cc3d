"""Map alignment, eq. (17): exact recovery, optimality against scipy, robustness, id matching."""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest
from scipy.optimize import minimize

from ekfslam.analysis.alignment import (
    Alignment,
    align,
    align_least_squares,
    align_mean_distance,
    mean_distance_objective,
)
from ekfslam.core.arena import SEED_TAG_POSITIONS
from ekfslam.errors import AlignmentError, ConfigError

# The seed's eight AprilTags (m) and its nominal start pose.
SEED_TAGS = np.array(SEED_TAG_POSITIONS)
NOMINAL_START = np.array([-0.375, -0.375, 0.0])
SOLVERS = [align_least_squares, align_mean_distance]


def world_from(params, est):
    """world = R(θ0) est + (x0, y0), written out with cos/sin (independent of the module)."""
    x0, y0, th = params
    c, s = math.cos(th), math.sin(th)
    est = np.asarray(est, dtype=float)
    return np.column_stack([c * est[:, 0] - s * est[:, 1] + x0, s * est[:, 0] + c * est[:, 1] + y0])


def estimate_from(params, world):
    """Inverse of `world_from`: est = R(θ0)ᵀ (world − (x0, y0))."""
    x0, y0, th = params
    c, s = math.cos(th), math.sin(th)
    dx, dy = world[:, 0] - x0, world[:, 1] - y0
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy])


def eq17(params, X, Y):
    """The seed's eq. (17), written out here so the checks do not lean on the module's copy."""
    return float(np.mean(np.linalg.norm(world_from(params, X) - Y, axis=1)))


def angle_diff(a, b):
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


def noisy_problem(rng, n, noise=0.05):
    """True map Y, a random transform, and the estimate X that it maps onto Y (plus noise)."""
    Y = rng.uniform(-1.0, 1.0, (n, 2))
    params = np.array([*rng.normal(0.0, 0.3, 2), rng.uniform(-math.pi, math.pi)])
    X = estimate_from(params, Y) + rng.normal(0.0, noise, (n, 2))
    return X, Y, params


def scipy_minimum(X, Y, starts):
    """Brute force eq. (17): Nelder-Mead from several starts, each polished by a restart."""
    options = {"xatol": 1e-9, "fatol": 1e-14, "maxiter": 20000, "maxfev": 20000}
    best = None
    for x0 in starts:
        res = minimize(eq17, x0, args=(X, Y), method="Nelder-Mead", options=options)
        # a restart rebuilds the simplex, which Nelder-Mead may have collapsed onto a kink
        res = minimize(eq17, res.x, args=(X, Y), method="Nelder-Mead", options=options)
        if best is None or res.fun < best.fun:
            best = res
    return best


# --- exact recovery --------------------------------------------------------------------------


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize(
    "theta", [math.pi - 1e-9, -math.pi, -math.pi + 1e-9, math.pi - 0.01, 0.0, 1.234, -2.5]
)
@pytest.mark.parametrize("n", [3, 4, 8, 20])
def test_exact_recovery_without_noise(solver, theta, n):
    rng = np.random.default_rng(n * 1000 + round(theta * 1e6) % 997)
    params = np.array([rng.normal(0, 2.0), rng.normal(0, 2.0), theta])
    X = rng.uniform(-1.5, 1.5, (n, 2))
    Y = world_from(params, X)
    result = solver(X, Y)
    assert abs(result.x0 - params[0]) < 1e-9
    assert abs(result.y0 - params[1]) < 1e-9
    assert angle_diff(result.theta0, theta) < 1e-9
    assert -math.pi <= result.theta0 < math.pi
    assert result.mean_error < 1e-12
    assert result.rmse < 1e-12
    assert result.converged


def test_table1_convention_world_is_rotated_estimate_plus_translation():
    # The seed's Table 1 (square run): (x0, y0, θ0) = (-0.020, 0.056, 0.142).
    table1 = np.array([-0.020, 0.056, 0.142])
    est = estimate_from(table1, SEED_TAGS)
    for solver in SOLVERS:
        result = solver(est, SEED_TAGS)
        np.testing.assert_allclose(result.transform, table1, atol=1e-12)
        # and not the inverse transform: the recovered one maps estimate -> world
        np.testing.assert_allclose(world_from(result.transform, est), SEED_TAGS, atol=1e-12)
        np.testing.assert_allclose(result.apply(est), SEED_TAGS, atol=1e-12)
        np.testing.assert_allclose(result.aligned, SEED_TAGS, atol=1e-12)


# --- optimality -------------------------------------------------------------------------------


@pytest.mark.slow
def test_mean_distance_beats_least_squares_on_its_objective_and_vice_versa():
    rng = np.random.default_rng(17)
    for trial in range(200):
        X, Y, _ = noisy_problem(rng, n=3 + trial % 10)
        ls, md = align_least_squares(X, Y), align_mean_distance(X, Y)
        assert md.converged
        assert md.mean_error <= ls.mean_error + 1e-12
        assert ls.rmse <= md.rmse + 1e-12


def test_objective_is_eq17_and_matches_result_fields():
    rng = np.random.default_rng(3)
    X, Y, _ = noisy_problem(rng, 6)
    params = np.array([0.1, -0.2, 0.3])
    assert mean_distance_objective(params, X, Y) == pytest.approx(eq17(params, X, Y), rel=1e-14)
    md = align_mean_distance(X, Y)
    assert md.mean_error == pytest.approx(mean_distance_objective(md.transform, X, Y), rel=1e-14)
    np.testing.assert_allclose(md.errors, np.linalg.norm(md.aligned - Y, axis=1), rtol=1e-14)
    assert md.rmse == pytest.approx(math.sqrt(np.mean(md.errors**2)), rel=1e-14)


@functools.cache
def _scipy_cases():
    """Noisy 5- and 8-landmark problems: two whose minimiser fits one landmark exactly (a kink
    of eq. 17) and two whose minimiser is smooth; both kinds are common."""
    rng = np.random.default_rng(2024)
    kinks, smooth = [], []
    for trial in range(100):
        X, Y, _ = noisy_problem(rng, n=5 if trial < 4 else 8)
        md = align_mean_distance(X, Y)
        (kinks if md.errors.min() < 1e-9 else smooth).append((X, Y, md))
        if len(kinks) >= 2 and len(smooth) >= 2:
            break
    return kinks[:2] + smooth[:2]


def test_kinked_minima_are_common():
    # The case mix below relies on this; a solver that never lands exactly on one landmark
    # (e.g. a smoothed objective) would fail here.
    cases = _scipy_cases()
    assert len(cases) == 4
    assert sum(md.errors.min() < 1e-9 for _, _, md in cases) == 2


@pytest.mark.parametrize("case", range(4))
def test_agrees_with_scipy_brute_force(case):
    X, Y, md = _scipy_cases()[case]
    rng = np.random.default_rng(case)
    ls = align_least_squares(X, Y).transform
    ref = scipy_minimum(X, Y, [ls, ls + rng.normal(0, 0.05, 3)])
    assert md.converged
    assert md.mean_error <= ref.fun + 1e-12  # never worse than the brute force
    assert abs(md.mean_error - ref.fun) < 1e-6
    np.testing.assert_allclose(md.transform[:2], ref.x[:2], atol=1e-6)
    assert angle_diff(md.theta0, ref.x[2]) < 1e-6


@pytest.mark.slow
def test_no_nearby_transform_is_better():
    # Local optimality without trusting any optimiser: probe eq. (17) around the answer along
    # random directions, and along the directions that keep the best-fitting landmark fitted
    # (where a kinked minimum is flattest).
    rng = np.random.default_rng(99)
    for trial in range(40):
        X, Y, _ = noisy_problem(rng, n=3 + trial % 8)
        md = align_mean_distance(X, Y)
        p, f = md.transform, md.mean_error
        for size in (1e-7, 1e-5, 1e-3):
            for direction in rng.normal(size=(20, 3)):
                probe = p + size * direction / np.linalg.norm(direction)
                assert eq17(probe, X, Y) >= f - 1e-15
            k = int(np.argmin(md.errors))
            for dtheta in (-size, size):
                th = p[2] + dtheta
                c, s = math.cos(th), math.sin(th)
                t = Y[k] - np.array([c * X[k, 0] - s * X[k, 1], s * X[k, 0] + c * X[k, 1]])
                assert eq17([t[0], t[1], th], X, Y) >= f - 1e-15


def test_minimum_with_two_landmarks_is_half_the_length_mismatch():
    # With two landmarks eq. (17) is at least |‖X1 − X2‖ − ‖Y1 − Y2‖| / 2 (triangle inequality)
    # and that bound is attained.
    X = np.array([[0.0, 0.0], [1.0, 0.0]])
    Y = np.array([[2.0, 1.0], [2.0, 2.3]])
    md = align_mean_distance(X, Y)
    assert md.mean_error == pytest.approx(0.15, abs=1e-12)
    assert md.converged


def test_iterations_for_the_seed_arena_with_5cm_noise():
    rng = np.random.default_rng(8)
    iterations = []
    for _ in range(50):
        est = estimate_from([0.03, -0.02, 0.1], SEED_TAGS) + rng.normal(0, 0.05, (8, 2))
        md = align_mean_distance(est, SEED_TAGS)
        assert md.converged
        iterations.append(md.iterations)
    assert np.median(iterations) < 40
    assert max(iterations) < 200


def test_max_iterations_is_respected():
    rng = np.random.default_rng(11)
    X, Y, _ = noisy_problem(rng, 8)
    md = align_mean_distance(X, Y, max_iterations=3)
    assert md.iterations <= 3
    # three IRLS steps from least squares lower eq. (17) but do not reach the minimum
    full = align_mean_distance(X, Y)
    assert full.mean_error <= md.mean_error <= align_least_squares(X, Y).mean_error + 1e-15


# --- robustness -------------------------------------------------------------------------------


def test_mean_distance_is_more_robust_to_an_outlier():
    rng = np.random.default_rng(5)
    truth_params = np.array([0.03, -0.02, 0.1])
    est = estimate_from(truth_params, SEED_TAGS) + rng.normal(0, 0.01, (8, 2))
    est[2] += [0.5, 0.3]  # one landmark placed ~0.6 m off
    inliers = np.arange(8) != 2
    ls, md = align_least_squares(est, SEED_TAGS), align_mean_distance(est, SEED_TAGS)
    ls_inlier, md_inlier = ls.errors[inliers].mean(), md.errors[inliers].mean()
    assert md_inlier < 0.3 * ls_inlier
    assert md_inlier < 0.02  # about the 1 cm noise
    assert ls_inlier > 0.05  # least squares smears the outlier over everyone
    # and the transform itself is recovered far better
    assert (
        np.abs(md.transform - truth_params).max() < 0.2 * np.abs(ls.transform - truth_params).max()
    )


# --- matching by id ---------------------------------------------------------------------------


def test_align_matches_ids_and_ignores_extras_on_either_side():
    rng = np.random.default_rng(21)
    params = np.array([0.2, -0.1, 2.9])
    true_ids = [1, 2, 3, 4, 5, 9]
    truth = {i: rng.uniform(-1, 1, 2) for i in true_ids}
    common = [2, 3, 5, 9]
    est_points = estimate_from(params, np.array([truth[i] for i in common]))
    estimated = {np.int64(i): p for i, p in zip(common, est_points, strict=True)}
    estimated[np.int64(7)] = np.array([5.0, 5.0])  # only in the estimate: must be ignored
    estimated = dict(reversed(list(estimated.items())))  # order must not matter
    for method in ("mean_distance", "least_squares"):
        result = align(estimated, truth, method=method)
        assert result.method == method
        np.testing.assert_array_equal(result.ids, common)
        np.testing.assert_allclose(result.truth, [truth[i] for i in common], atol=0)
        np.testing.assert_allclose(result.transform, params, atol=1e-12)
        np.testing.assert_allclose(result.aligned, result.truth, atol=1e-12)


@pytest.mark.parametrize(
    ("estimated", "truth", "found"),
    [({1: (0, 0), 2: (1, 0)}, {3: (0, 0), 4: (1, 1)}, 0), ({1: (0, 0), 2: (1, 0)}, {2: (0, 0)}, 1)],
)
def test_too_few_common_landmarks(estimated, truth, found):
    with pytest.raises(AlignmentError) as info:
        align(estimated, truth)
    message = str(info.value)
    assert "\n" not in message
    assert f"found {found}" in message
    assert "at least 2" in message
    assert "estimated ids [1, 2]" in message
    assert f"true ids [{', '.join(str(i) for i in truth)}]" in message


def test_bad_inputs_raise_alignment_error():
    pts = {1: (0.0, 0.0), 2: (1.0, 0.0)}
    # a bad argument is a ConfigError (a ValueError), not an AlignmentError: `summarize` reports
    # an AlignmentError as "no alignment", and an unknown method must never read so (issue 27)
    with pytest.raises(ConfigError, match=r"align: method must be one of .*got 'icp'"):
        align(pts, pts, method="icp")
    with pytest.raises(ConfigError, match="integers"):
        align({1.5: (0.0, 0.0), 2: (1.0, 0.0)}, pts)
    with pytest.raises(AlignmentError, match=r"shape \(N, 2\)"):
        align_mean_distance(np.zeros((3, 2)), np.zeros((4, 2)))
    with pytest.raises(AlignmentError, match="finite"):
        align_least_squares([[0.0, np.nan], [1.0, 0.0]], [[0.0, 0.0], [1.0, 0.0]])


# --- poses and the start ----------------------------------------------------------------------


@pytest.mark.parametrize("solver", SOLVERS)
def test_start_pose_recovers_the_true_start(solver):
    s = NOMINAL_START + np.array([0.03, -0.02, 0.1])
    # The robot believed it stood at the nominal start n when it really stood at s, so every
    # landmark it mapped sits at T_n ∘ T_s⁻¹ (true position).
    c, si = math.cos(s[2]), math.sin(s[2])
    in_robot = (SEED_TAGS - s[:2]) @ np.array([[c, -si], [si, c]])  # T_s⁻¹
    believed = world_from(NOMINAL_START, in_robot)  # T_n
    result = solver(believed, SEED_TAGS)
    np.testing.assert_allclose(result.start_pose(NOMINAL_START), s, atol=1e-9)
    assert result.mean_error < 1e-12


def test_apply_pose_rotates_translates_and_wraps_heading():
    result = align_least_squares(
        estimate_from([1.0, 2.0, 3.0], SEED_TAGS), SEED_TAGS
    )  # θ0 = 3.0 rad
    pose = np.array([0.5, -0.25, 0.5])
    out = result.apply_pose(pose)
    np.testing.assert_allclose(out[:2], world_from([1.0, 2.0, 3.0], pose[None, :2])[0], atol=1e-12)
    assert out[2] == pytest.approx(3.5 - 2 * math.pi, abs=1e-12)  # wrapped into [-π, π)
    assert out.shape == (3,)
    np.testing.assert_allclose(result.apply(np.zeros((1, 2))), [[1.0, 2.0]], atol=1e-12)


def test_result_is_immutable_and_well_formed():
    rng = np.random.default_rng(1)
    X, Y, _ = noisy_problem(rng, 5)
    result = align_mean_distance(X, Y)
    assert isinstance(result, Alignment)
    with pytest.raises(dataclasses.FrozenInstanceError):
        result.x0 = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        result.errors[0] = 0.0
    assert result.ids.dtype.kind == "i"
    np.testing.assert_array_equal(result.ids, np.arange(5))
    assert result.aligned.shape == result.truth.shape == (5, 2)
    assert result.errors.shape == (5,)
    assert isinstance(result.iterations, int)
    assert result.iterations > 0
