"""The notebooks' exercises and their checks: a verdict that says what is wrong, not the answer.

`check_answer` compares a number a student typed in; `check_prediction` compares an outcome the
student predicted (a word, typed in before the experiment runs) with what the experiment gave, and
explains it either way. The `check_*` functions take a function the
student wrote in a notebook (exercises 1-3 of the lab: the mecanum twist of eq. (4) and its
noise; G, V of eq. (7) with sympy and R = V M Vᵀ; the prediction of eq. (9) in block form; the
map's exercises are in `ekfslam.teaching.map_exercises`), run it on fixed and random inputs against
the package's answer and print one verdict. A stub that still raises NotImplementedError gets
"not done yet". Each returns True only when every case agrees,
so the notebook's next cells use the student's function then and the package's otherwise.

Names follow the seed and Thrun: R is the motion noise and Q the measurement noise (Labbe's
book and filterpy use the reverse).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ekfslam.core.kinematics import MecanumGeometry, wheel_noise_to_twist_covariance
from ekfslam.core.models import (
    motion,
    motion_control_jacobian,
    motion_jacobian,
    motion_noise,
)
from ekfslam.core.steps import predict_step
from ekfslam.geometry import wrap_angle
from ekfslam.teaching.verdicts import (
    CONTROL_NAMES,
    POSE_NAMES,
    RNG_SEED,
    TWIST,
    WHEELS,
    Array,
    Wrong,
    as_array,
    attempt,
    close,
    entry_verdict,
    evaluate,
)


def check_answer(answer: object, expected: ArrayLike, atol: float = 1e-6) -> bool:
    """Compare an exercise's answer with the expected value and print a verdict.

    Returns True when `answer` has the expected shape and agrees within `atol`; None (not
    answered yet) and anything of the wrong shape print a hint instead of raising.
    """
    if answer is None:
        print("Not answered yet: replace None with your answer and run this cell again.")
        return False
    try:
        got = np.asarray(answer, dtype=float)
        want = np.asarray(expected, dtype=float)
        if got.shape != want.shape:
            print(f"Not yet: the answer has shape {got.shape}, the expected one {want.shape}.")
            return False
        ok = bool(np.allclose(got, want, rtol=0.0, atol=atol))
    except (TypeError, ValueError):
        print(f"Not yet: {answer!r} is not a number or an array of numbers.")
        return False
    print("Right!" if ok else f"Not yet: off by up to {np.max(np.abs(got - want)):.3g}.")
    return ok


def check_prediction(prediction: object, outcome: str, choices: Sequence[str], why: str) -> bool:
    """Compare a predicted outcome with the one the experiment gave, and say why it happened.

    `prediction` is what the student wrote before running the experiment (one of `choices`, or
    None while unanswered); `outcome` is the choice the experiment's numbers give; `why` is the
    explanation, shown once a prediction is made, whether it was right or not. Returns True when
    the prediction matches.
    """
    if outcome not in choices:
        raise ValueError(f"outcome {outcome!r} is not one of {list(choices)}")
    listed = " or ".join(repr(c) for c in choices)
    if prediction is None:
        print(f"Not answered yet: write your prediction ({listed}) before you run the experiment.")
        return False
    if prediction not in choices:
        print(f"Not yet: {prediction!r} is not one of the choices ({listed}).")
        return False
    if prediction == outcome:
        print(f"Right: {outcome}. {why}")
        return True
    print(f"Not what happened: you predicted {prediction!r}; the experiment: {outcome!r}. {why}")
    return False


# --- write-it-yourself exercises ----------------------------------------------------------------
# Each check_* runs the student's function on fixed and random inputs against the package's answer
# and prints one verdict that names what is wrong without giving the right value. It returns True
# only when every case agrees, so a notebook can fall back to the package's function otherwise.


# --- exercise 1: the mecanum twist, eq. (4) -----------------------------------------------------


def _geometries() -> list[MecanumGeometry]:
    rng = np.random.default_rng(RNG_SEED)
    return [MecanumGeometry()] + [
        MecanumGeometry(*rng.uniform([0.02, 0.05, 0.04], [0.06, 0.15, 0.12])) for _ in range(3)
    ]


def check_twist(twist_from_wheels: Callable[[Array, MecanumGeometry], object]) -> bool:
    """Exercise 1a: `twist_from_wheels(wheels (4,) rad/s, geometry) -> (vx, vy, ωz)`, eq. (4)."""

    def check() -> None:
        rng = np.random.default_rng(RNG_SEED)
        for k, geometry in enumerate(_geometries()):
            J = geometry.wheels_to_twist_matrix
            mine = np.column_stack(
                [as_array(twist_from_wheels(w, geometry), (3,), "your twist") for w in np.eye(4)]
            )
            if k > 0 and not close(mine, J):
                raise Wrong(
                    "right for the default robot only: use the geometry's wheel_radius, lx "
                    "and ly, not numbers."
                )
            for i, name in enumerate(TWIST):
                if close(mine[i], -J[i]):
                    raise Wrong(f"{name} has the wrong sign for every wheel.")
                scale = mine[i] @ J[i] / (J[i] @ J[i])
                if not close(scale, 1.0) and close(mine[i], scale * J[i]):
                    raise Wrong(f"{name} has the right signs but the wrong factor in front.")
            entry_verdict(mine, J, "J", TWIST, WHEELS)
            w = rng.uniform(-8, 8, 4)
            if not close(as_array(twist_from_wheels(w, geometry), (3,), "your twist"), J @ w):
                raise Wrong("right for one wheel at a time but not for several: is it linear?")

    return attempt("1a", check)


def check_twist_covariance(twist_covariance: Callable[[object, MecanumGeometry], object]) -> bool:
    """Exercise 1b: `twist_covariance(wheel_sigma (4,) rad/s, geometry) -> (3, 3)` covariance
    of (vx, vy, ωz) from independent wheel-speed noise (the seed's Section 2.2)."""

    def check() -> None:
        rng = np.random.default_rng(RNG_SEED)
        for geometry in _geometries():
            sigma = rng.uniform(0.05, 0.5, 4)
            want = wheel_noise_to_twist_covariance(sigma, geometry)
            got = as_array(twist_covariance(sigma, geometry), (3, 3), "your covariance")
            J = geometry.wheels_to_twist_matrix
            if close(got, J @ np.diag(sigma) @ J.T):
                raise Wrong(
                    "the wheel noise enters as standard deviations; a covariance needs variances."
                )
            if not close(got, got.T):
                raise Wrong("your covariance is not symmetric.")
            entry_verdict(got, want, "Cov", TWIST, TWIST)

    return attempt("1b", check)


# --- exercise 2: G and V of eq. (7) with sympy, and R = V M Vᵀ ----------------------------------


def _poses_and_controls() -> list[tuple[Array, Array]]:
    rng = np.random.default_rng(RNG_SEED)
    fixed = [(np.array([0.1, -0.2, 0.3]), np.array([0.05, 0.01, 0.02]))]
    return fixed + [
        (rng.uniform([-1, -1, -np.pi], [1, 1, np.pi]), rng.uniform(-0.1, 0.1, 3)) for _ in range(4)
    ]


def check_motion_jacobians(derive: Callable[[], tuple[object, object]]) -> bool:
    """Exercise 2a: `derive() -> (G, V)`, sympy matrices ∂f/∂pose (eq. 7) and ∂f/∂u of eq. (6),
    in the symbols x, y, theta, du_x, du_y, dtheta of `ekfslam.teaching.derivations`."""

    def check() -> None:
        result = derive()
        if not isinstance(result, tuple) or len(result) != 2:
            raise Wrong("derive() should return the pair (G, V).")
        G, V = result
        for pose, u in _poses_and_controls():
            names = ("x", "y", "theta", "du_x", "du_y", "dtheta")
            values = dict(zip(names, [*pose, *u], strict=True))
            want_G, want_V = motion_jacobian(pose, u), motion_control_jacobian(pose)
            got_G = as_array(evaluate(G, values, "G"), (3, 3), "G")
            got_V = as_array(evaluate(V, values, "V"), (3, 3), "V")
            if close(got_G, want_V) and close(got_V, want_G):
                raise Wrong("G and V are swapped: G is the derivative by the pose.")
            if not close(got_G, want_G) and close(got_G.T, want_G):
                raise Wrong("G is transposed: row i is f_i, column j the derivative by pose_j.")
            entry_verdict(got_G, want_G, "G", POSE_NAMES, POSE_NAMES)
            entry_verdict(got_V, want_V, "V", POSE_NAMES, CONTROL_NAMES)

    return attempt("2a", check)


def check_motion_noise(motion_noise_R: Callable[[Array, Array], object]) -> bool:
    """Exercise 2b: `motion_noise_R(pose (3,), M (3, 3)) -> R = V M Vᵀ (3, 3)`: the control
    noise M (robot frame, u-space) in the state's coordinates (the seed's and Thrun's R)."""

    def check() -> None:
        rng = np.random.default_rng(RNG_SEED)
        for pose, _ in _poses_and_controls():
            A = rng.normal(size=(3, 3))
            M = A @ A.T * 1e-4 + np.diag([1e-4, 4e-4, 1e-3])  # correlated, so V M Vᵀ ≠ M
            got = as_array(motion_noise_R(pose, M.copy()), (3, 3), "your R")
            V = motion_control_jacobian(pose)
            if not close(got, motion_noise(pose, M)):
                if close(got, M):
                    raise Wrong("R equals M: M is in the robot's frame, R in the world's.")
                if close(got, V.T @ M @ V):
                    raise Wrong("the rotation is on the wrong side (Vᵀ M V instead of V M Vᵀ).")
                if not close(got, got.T):
                    raise Wrong("your R is not symmetric.")
                entry_verdict(got, motion_noise(pose, M), "R", POSE_NAMES, POSE_NAMES)

    return attempt("2b", check)


# --- exercise 3: the prediction in block form, eq. (9) ------------------------------------------


def _states(rng: np.random.Generator) -> list[tuple[Array, Array, Array, Array]]:
    """(mu, Sigma, u, R) with 0, 1 and 3 landmarks; the first heading is near π so that a
    missing wrap shows, and every Σ is a random full covariance so that every block matters."""
    cases = []
    for n, heading in ((1, 3.1), (0, -0.5), (3, 1.0), (2, -3.1)):
        d = 3 + 2 * n
        mu = np.concatenate([[*rng.uniform(-1, 1, 2), heading], rng.uniform(-1, 1, 2 * n)])
        A = rng.normal(size=(d, d))
        Sigma = 1e-3 * (A @ A.T + np.eye(d))
        u = np.array([0.08, 0.02, 0.1 * np.sign(heading)])
        B = rng.normal(size=(3, 3))
        cases.append((mu, Sigma, u, 1e-4 * (B @ B.T + np.eye(3))))
    return cases


def check_predict(predict: Callable[[Array, Array, Array, Array], object]) -> bool:
    """Exercise 3: `predict(mu (d,), Sigma (d, d), u (3,), R (3, 3)) -> (mu, Sigma)`, eq. (9)
    in block form (the answer is `ekfslam.core.steps.predict_step`)."""

    def check() -> None:
        for mu, Sigma, u, R in _states(np.random.default_rng(RNG_SEED)):
            d = mu.size
            result = predict(mu.copy(), Sigma.copy(), u.copy(), R.copy())
            if not isinstance(result, tuple) or len(result) != 2:
                raise Wrong("predict should return the pair (mu, Sigma).")
            got_mu = as_array(result[0], (d,), f"mu (with {(d - 3) // 2} landmarks)")
            got_S = as_array(result[1], (d, d), f"Sigma (with {(d - 3) // 2} landmarks)")
            want_mu, want_S = predict_step(mu, Sigma, u, R)
            _check_predicted_mean(got_mu, want_mu, mu)
            _check_predicted_covariance(got_S, want_S, Sigma, mu, u, R)

    return attempt("3", check)


def _check_predicted_mean(got: Array, want: Array, before: Array) -> None:
    if not close(got[3:], before[3:]):
        raise Wrong("the landmarks in mu moved: a prediction leaves them where they are.")
    if not close(got[:2], want[:2]):
        raise Wrong("the predicted position (x, y) is wrong (eq. 6).")
    if not close(got[2], want[2]):
        if close(wrap_angle(float(got[2])), want[2]):
            raise Wrong("your heading is not wrapped to [-π, π).")
        raise Wrong("the predicted heading θ is wrong (eq. 6).")


def _check_predicted_covariance(
    got: Array, want: Array, before: Array, mu: Array, u: Array, R: Array
) -> None:
    r, m = slice(0, 3), slice(3, None)
    if not close(got[m, m], before[m, m]):
        raise Wrong("Σ[m, m] changed: a prediction does not touch the landmark block.")
    if not close(got[r, r], want[r, r]):
        G = motion_jacobian(mu[:3], u)
        G_after = motion_jacobian(motion(mu[:3], u), u)
        if close(got[r, r], want[r, r] - R):
            raise Wrong("the motion noise R is missing from Σ[r, r].")
        if close(got[r, r], G_after @ before[r, r] @ G_after.T + R):
            raise Wrong(
                "G is evaluated at the pose after the motion; eq. (7) takes the one before."
            )
        if close(got[r, r], G.T @ before[r, r] @ G + R):
            raise Wrong("Σ[r, r] has G and Gᵀ the wrong way round.")
        raise Wrong("Σ[r, r] is wrong.")
    if got.shape[0] > 3:
        if close(got[r, m], before[r, m]):
            raise Wrong("the robot-landmark cross-covariance Σ[r, m] is not updated.")
        if not close(got[r, m], want[r, m]):
            raise Wrong("the robot-landmark cross-covariance Σ[r, m] is wrong.")
        if not close(got[m, r], want[m, r]):
            raise Wrong("Σ[m, r] does not match Σ[r, m]ᵀ: Σ must stay symmetric.")
