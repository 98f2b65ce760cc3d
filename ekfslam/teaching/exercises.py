"""The notebooks' exercises and their checks: a verdict that says what is wrong, not the answer.

`check_answer` compares a number a student typed in; `check_prediction` compares an outcome the
student predicted (a word, typed in before the experiment runs) with what the experiment gave, and
explains it either way; given a `key`, the first prediction is recorded beside the notebook
(`PREDICTIONS`) and stays the one that counts. The `check_*` functions take a function the student
wrote in a notebook (exercises 1-3 of the lab: the mecanum twist of eq. (4) and its noise; G, V of
eq. (7) with sympy and R = V M Vᵀ; the prediction of eq. (9) in block form; the map's exercises
are in `ekfslam.teaching.map_exercises`), run it on fixed and random inputs and print one verdict
(`ekfslam.teaching.verdicts`). Each returns True only when every case agrees, so the notebook's
next cells use the student's function then and the package's otherwise.

Names follow the seed and Thrun: R is the motion noise and Q the measurement noise (Labbe's
book and filterpy use the reverse).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ekfslam.core import models
from ekfslam.core.kinematics import MecanumGeometry, wheel_noise_to_twist_covariance
from ekfslam.core.models import (
    motion,
    motion_control_jacobian,
    motion_jacobian,
    motion_noise,
)
from ekfslam.core.steps import predict_step
from ekfslam.files import atomic_write_text
from ekfslam.geometry import wrap_angle
from ekfslam.teaching.verdicts import (
    CONTROL_NAMES,
    POSE_NAMES,
    TWIST,
    WHEELS,
    Array,
    Exercise,
    Wrong,
    as_array,
    attempt,
    close,
    entry_verdict,
    evaluate,
)

#: Set by the book's build for the notebooks it executes (docs/conf.py).
BOOK = "EKFSLAM_BOOK"
#: The file beside the notebook that keeps each prediction's first answer (`check_prediction`).
PREDICTIONS = "lab-predictions.json"


def in_the_book() -> bool:
    """True when the notebook runs to be a page of the book (``EKFSLAM_BOOK=1``, docs/conf.py)."""
    return os.environ.get(BOOK, "") == "1"


def check_answer(answer: object, expected: ArrayLike, atol: float = 1e-6) -> bool:
    """Compare an exercise's answer with the expected value and print a verdict.

    Returns True when `answer` has the expected shape and agrees within `atol`; None (not
    answered yet) and anything of the wrong shape print a hint instead of raising.
    """
    if answer is None:
        if in_the_book():  # the book's page shows the worked answer
            print(f"The answer: {np.array2string(np.asarray(expected), precision=6)}.")
            return True
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


def recorded_predictions(folder: Path | None = None) -> dict[str, str]:
    """The first predictions recorded in `PREDICTIONS` in `folder` (default: the current one,
    which Jupyter makes the notebook's own); {} when there is none or it is unreadable."""
    path = (folder or Path.cwd()) / PREDICTIONS
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}


def _record(key: str, prediction: str) -> None:
    recorded = recorded_predictions()
    recorded[key] = prediction
    try:
        atomic_write_text(
            Path.cwd() / PREDICTIONS, json.dumps(recorded, indent=1, sort_keys=True) + "\n"
        )
    except OSError as error:  # a read-only folder: the prediction still counts this session
        print(f"(could not record your prediction in {PREDICTIONS}: {error.strerror})")


def check_prediction(
    prediction: object,
    outcome: str,
    choices: Sequence[str],
    why: str,
    key: str | None = None,
) -> bool:
    """Compare a predicted outcome with the one the experiment gave, and say why it happened.

    `prediction` is what the student wrote before running the experiment (one of `choices`, or
    None while unanswered); `outcome` is the choice the experiment's numbers give; `why` is the
    explanation, shown once a prediction is made, whether it was right or not. Returns True when
    the prediction matches.

    With a `key` the first valid prediction is recorded in `PREDICTIONS` beside the notebook and
    is the one judged ever after: changing the cell and running it again after seeing the outcome
    does not change it. The grader reads the recorded file the student hands in, and nothing
    else (`ekfslam.cli.lab_worker.grade_predictions`).
    """
    if outcome not in choices:
        raise ValueError(f"outcome {outcome!r} is not one of {list(choices)}")
    listed = " or ".join(repr(c) for c in choices)
    if in_the_book():
        # a reader of the book predicts nothing: the experiment answers, and no file is written
        # beside the notebook (the book's build runs in the checkout)
        if prediction is None:
            print(f"The experiment: {outcome}. {why}")
            return True
        key = None
    first = recorded_predictions().get(key) if key is not None else None
    if first is not None and first in choices:
        if prediction != first:
            print(
                f"Your first prediction, {first!r}, is recorded ({PREDICTIONS}) and is the one "
                "that counts."
            )
        prediction = first
    if prediction is None:
        print(f"Not answered yet: write your prediction ({listed}) before you run the experiment.")
        return False
    if prediction not in choices:
        print(f"Not yet: {prediction!r} is not one of the choices ({listed}).")
        return False
    if key is not None and first is None:
        _record(key, str(prediction))
    if prediction == outcome:
        print(f"Right: {outcome}. {why}")
        return True
    print(f"Not what happened: you predicted {prediction!r}; the experiment: {outcome!r}. {why}")
    return False


# --- write-it-yourself exercises ----------------------------------------------------------------
# Each exercise is its cases and a judge (`ekfslam.teaching.verdicts.Exercise`); its check_* runs
# the notebook's fixed cases and prints one verdict that names what is wrong without giving the
# right value. The grader runs the same judge on cases drawn at release time.


# --- exercise 1: the mecanum twist, eq. (4) -----------------------------------------------------


def _twist_cases(rng: np.random.Generator) -> list[dict]:
    """The default robot and three random ones; each with a random set of wheel speeds."""
    geometries = [MecanumGeometry()] + [
        MecanumGeometry(*rng.uniform([0.02, 0.05, 0.04], [0.06, 0.15, 0.12])) for _ in range(3)
    ]
    default = MecanumGeometry().wheels_to_twist_matrix
    return [
        {"geometry": g, "J": g.wheels_to_twist_matrix, "default_J": default, "w": w}
        for g, w in zip(geometries, rng.uniform(-8, 8, (4, 4)), strict=True)
    ]


def _judge_twist(call: Callable, case: dict) -> None:
    g, J = case["geometry"], case["J"]
    mine = np.column_stack(
        [
            as_array(call(("wheel speeds", w), ("geometry", g)), (3,), "your twist")
            for w in np.eye(4)
        ]
    )
    if close(mine, 0.0) and not close(J, 0.0):
        raise Wrong("your twist is zero for every wheel speed.")
    if not close(mine, J) and close(mine, case["default_J"]):
        raise Wrong(
            "right for the default robot only: use the geometry's wheel_radius, lx and ly, not "
            "numbers."
        )
    for i, name in enumerate(TWIST):
        if close(mine[i], 0.0):
            raise Wrong(f"{name} is zero for every wheel speed.")
        if close(mine[i], -J[i]):
            raise Wrong(f"{name} has the wrong sign for every wheel.")
        scale = mine[i] @ J[i] / (J[i] @ J[i])
        if not close(scale, 1.0) and close(mine[i], scale * J[i]):
            raise Wrong(f"{name} has the right signs but the wrong factor in front.")
    entry_verdict(mine, J, "J", TWIST, WHEELS)
    w = case["w"]
    if not close(as_array(call(("wheels", w), ("geometry", g)), (3,), "your twist"), J @ w):
        raise Wrong("right for one wheel at a time but not for several: is it linear?")


#: what computes a twist or its noise from wheel speeds: left out while 1a or 1b is graded
_TWIST_WORK = (
    "ekfslam.core.kinematics:wheels_to_twist",
    "ekfslam.core.kinematics:twist_to_wheels",
    "ekfslam.core.kinematics:wheel_noise_to_twist_covariance",
    "ekfslam.core.kinematics:MecanumGeometry.twist_to_wheels_matrix",
)

TWIST_EXERCISE = Exercise(
    "1a",
    "twist_from_wheels",
    _twist_cases,
    _judge_twist,
    keeps=("ekfslam.core.kinematics",),
    denies=(*_TWIST_WORK, "ekfslam.core.kinematics:MecanumGeometry.wheels_to_twist_matrix"),
)


def check_twist(twist_from_wheels: Callable[[Array, MecanumGeometry], object]) -> bool:
    """Exercise 1a: `twist_from_wheels(wheels (4,) rad/s, geometry) -> (vx, vy, ωz)`, eq. (4)."""
    return attempt(TWIST_EXERCISE, twist_from_wheels)


def _twist_covariance_cases(rng: np.random.Generator) -> list[dict]:
    cases = []
    for g in [MecanumGeometry()] + [
        MecanumGeometry(*rng.uniform([0.02, 0.05, 0.04], [0.06, 0.15, 0.12])) for _ in range(3)
    ]:
        sigma = rng.uniform(0.05, 0.5, 4)
        cases.append(
            {"geometry": g, "sigma": sigma, "want": wheel_noise_to_twist_covariance(sigma, g)}
        )
    return cases


def _judge_twist_covariance(call: Callable, case: dict) -> None:
    g, sigma, want = case["geometry"], case["sigma"], case["want"]
    got = as_array(call(("wheel σ", sigma), ("geometry", g)), (3, 3), "your covariance")
    J = g.wheels_to_twist_matrix
    if close(got, want):
        return
    if close(got, J @ np.diag(sigma) @ J.T):
        raise Wrong("the wheel noise enters as standard deviations; a covariance needs variances.")
    if close(got, np.diag(np.diag(want))):
        raise Wrong("your covariance has no off-diagonal terms: vx and ωz share the wheels' noise.")
    if not close(got, got.T):
        raise Wrong("your covariance is not symmetric.")
    entry_verdict(got, want, "Cov", TWIST, TWIST)


TWIST_COVARIANCE_EXERCISE = Exercise(
    "1b",
    "twist_covariance",
    _twist_covariance_cases,
    _judge_twist_covariance,
    allowed=lambda: (MecanumGeometry.wheels_to_twist_matrix,),  # exercise 1a's J
    keeps=("ekfslam.core.kinematics",),
    denies=_TWIST_WORK,
)


def check_twist_covariance(twist_covariance: Callable[[object, MecanumGeometry], object]) -> bool:
    """Exercise 1b: `twist_covariance(wheel_sigma (4,) rad/s, geometry) -> (3, 3)` covariance
    of (vx, vy, ωz) from independent wheel-speed noise (the seed's Section 2.2)."""
    return attempt(TWIST_COVARIANCE_EXERCISE, twist_covariance)


# --- exercise 2: G and V of eq. (7) with sympy, and R = V M Vᵀ ----------------------------------


def _poses_and_controls(rng: np.random.Generator) -> list[tuple[Array, Array]]:
    fixed = (
        rng.uniform([-1, -1, 0.1], [1, 1, 1.0]),
        rng.uniform([0.02, -0.05, 0.01], [0.1, 0.05, 0.05]),
    )
    return [fixed] + [
        (rng.uniform([-1, -1, -np.pi], [1, 1, np.pi]), rng.uniform(-0.1, 0.1, 3)) for _ in range(4)
    ]


def _jacobian_cases(rng: np.random.Generator) -> list[dict]:
    return [
        {"pose": p, "u": u, "G": motion_jacobian(p, u), "V": motion_control_jacobian(p)}
        for p, u in _poses_and_controls(rng)
    ]


def _judge_motion_jacobians(call: Callable, case: dict) -> None:
    result = call()
    if not isinstance(result, tuple) or len(result) != 2:
        raise Wrong("derive() should return the pair (G, V).")
    G, V = result
    names = ("x", "y", "theta", "du_x", "du_y", "dtheta")
    values = dict(zip(names, [*case["pose"], *case["u"]], strict=True))
    want_G, want_V = case["G"], case["V"]
    got_G = as_array(evaluate(G, values, "G"), (3, 3), "G")
    got_V = as_array(evaluate(V, values, "V"), (3, 3), "V")
    if close(got_G, want_V) and close(got_V, want_G):
        raise Wrong("G and V are swapped: G is the derivative by the pose.")
    if not close(got_G, want_G) and close(got_G.T, want_G):
        raise Wrong("G is transposed: row i is f_i, column j the derivative by pose_j.")
    entry_verdict(got_G, want_G, "G", POSE_NAMES, POSE_NAMES)
    entry_verdict(got_V, want_V, "V", POSE_NAMES, CONTROL_NAMES)


MOTION_JACOBIANS_EXERCISE = Exercise(
    "2a",
    "derive_motion_jacobians",
    _jacobian_cases,
    _judge_motion_jacobians,
    numeric=False,
    differentiates=True,
    keeps=("ekfslam.teaching.symbols", "ekfslam.core.models"),
    denies=(
        "ekfslam.core.models:motion_jacobian",
        "ekfslam.core.models:motion_control_jacobian",
        "ekfslam.core.models:motion_noise",
    ),
)


def check_motion_jacobians(derive: Callable[[], tuple[object, object]]) -> bool:
    """Exercise 2a: `derive() -> (G, V)`, sympy matrices ∂f/∂pose (eq. 7) and ∂f/∂u of eq. (6),
    derived by sympy from f in the symbols x, y, theta, du_x, du_y, dtheta of
    `ekfslam.teaching.derivations`."""
    return attempt(MOTION_JACOBIANS_EXERCISE, derive)


def _motion_noise_cases(rng: np.random.Generator) -> list[dict]:
    cases = []
    for pose, _ in _poses_and_controls(rng):
        A = rng.normal(size=(3, 3))
        M = A @ A.T * 1e-4 + np.diag([1e-4, 4e-4, 1e-3])  # correlated, so V M Vᵀ ≠ M
        cases.append({"pose": pose, "M": M, "want": motion_noise(pose, M)})
    return cases


def _judge_motion_noise(call: Callable, case: dict) -> None:
    pose, M, want = case["pose"], case["M"], case["want"]
    got = as_array(call(("pose", pose), ("M", M)), (3, 3), "your R")
    if close(got, want):
        return
    V = motion_control_jacobian(pose)
    if close(got, M):
        raise Wrong("R equals M: M is in the robot's frame, R in the world's.")
    if close(got, V.T @ M @ V):
        raise Wrong("the rotation is on the wrong side (Vᵀ M V instead of V M Vᵀ).")
    if close(got, V @ M):
        raise Wrong("R = V M is missing the Vᵀ on the right: R = V M Vᵀ.")
    if not close(got, got.T):
        raise Wrong("your R is not symmetric.")
    entry_verdict(got, want, "R", POSE_NAMES, POSE_NAMES)


MOTION_NOISE_EXERCISE = Exercise(
    "2b",
    "motion_noise_R",
    _motion_noise_cases,
    _judge_motion_noise,
    keeps=("ekfslam.teaching.symbols", "ekfslam.core.models"),
    denies=("ekfslam.core.models:motion_noise", "ekfslam.core.models:motion_control_jacobian"),
)


def check_motion_noise(motion_noise_R: Callable[[Array, Array], object]) -> bool:
    """Exercise 2b: `motion_noise_R(pose (3,), M (3, 3)) -> R = V M Vᵀ (3, 3)`: the control
    noise M (robot frame, u-space) in the state's coordinates (the seed's and Thrun's R)."""
    return attempt(MOTION_NOISE_EXERCISE, motion_noise_R)


# --- exercise 3: the prediction in block form, eq. (9) ------------------------------------------


def _predict_cases(rng: np.random.Generator) -> list[dict]:
    """(mu, Sigma, u, R) with 0 to 3 landmarks; the first and last headings lie near ±π and turn
    across it, so that a missing wrap shows, and every Σ is a random full covariance so that
    every block matters."""
    cases = []
    near = np.pi - rng.uniform(0.01, 0.04)
    for n, heading in ((1, near), (0, rng.uniform(-1, 0)), (3, rng.uniform(0, 1)), (2, -near)):
        d = 3 + 2 * n
        mu = np.concatenate([[*rng.uniform(-1, 1, 2), heading], rng.uniform(-1, 1, 2 * n)])
        A = rng.normal(size=(d, d))
        Sigma = 1e-3 * (A @ A.T + np.eye(d))
        u = np.array([*rng.uniform([0.04, -0.03], [0.1, 0.03]), 0.1 * np.sign(heading)])
        B = rng.normal(size=(3, 3))
        R = 1e-4 * (B @ B.T + np.eye(3))
        want_mu, want_Sigma = predict_step(mu, Sigma, u, R)
        cases.append({"mu": mu, "Sigma": Sigma, "u": u, "R": R, "want": (want_mu, want_Sigma)})
    return cases


def _judge_predict(call: Callable, case: dict) -> None:
    mu, Sigma, u, R = case["mu"], case["Sigma"], case["u"], case["R"]
    d = mu.size
    result = call(("μ", mu), ("Σ", Sigma), ("u", u), ("R", R))
    if not isinstance(result, tuple | list) or len(result) != 2:
        raise Wrong("predict should return the pair (mu, Sigma).")
    got_mu = as_array(result[0], (d,), f"mu (with {(d - 3) // 2} landmarks)")
    got_S = as_array(result[1], (d, d), f"Sigma (with {(d - 3) // 2} landmarks)")
    want_mu, want_S = case["want"]
    _check_predicted_mean(got_mu, want_mu, mu)
    _check_predicted_covariance(got_S, want_S, Sigma, mu, u, R)


def _check_predicted_mean(got: Array, want: Array, before: Array) -> None:
    if not close(got[3:], before[3:]):
        raise Wrong("the landmarks in mu moved: a prediction leaves them where they are.")
    if not close(got[:2], want[:2]):
        raise Wrong("the predicted position (x, y) is wrong (eq. 6).")
    if not close(got[2], want[2]):
        if close(wrap_angle(float(got[2])), want[2]):
            raise Wrong("your heading is not wrapped to [-π, π).")
        raise Wrong("the predicted heading θ is wrong (eq. 6).")


def _students_G(got: Array, before: Array) -> Array | None:
    """The G a student's Σ[r, m] = G Σ[r, m] was made with (exact with two landmarks or more)."""
    r, m = slice(0, 3), slice(3, None)
    if before.shape[0] < 7:
        return None
    G = got[r, m] @ np.linalg.pinv(before[r, m])
    return G if close(G @ before[r, m], got[r, m]) else None


def _one_entry_off(got_rr: Array, before_rr: Array, G: Array, R: Array) -> Array | None:
    """The G with one entry negated or left out that gives the student's Σ[r, r], or None."""
    for i in range(3):
        for j in range(3):
            for value in (-G[i, j], 0.0, 1.0 - G[i, j] if i == j else G[i, j]):
                other = G.copy()
                other[i, j] = value
                if not close(other, G) and close(got_rr, other @ before_rr @ other.T + R):
                    return other
    return None


def _check_predicted_covariance(
    got: Array, want: Array, before: Array, mu: Array, u: Array, R: Array
) -> None:
    r, m = slice(0, 3), slice(3, None)
    G = motion_jacobian(mu[:3], u)
    if not close(got[m, m], before[m, m]):
        raise Wrong("Σ[m, m] changed: a prediction does not touch the landmark block.")
    if not close(got[r, r], want[r, r]):
        G_after = motion_jacobian(motion(mu[:3], u), u)
        if close(got[r, r], want[r, r] - R):
            raise Wrong("the motion noise R is missing from Σ[r, r].")
        if close(got[r, r], G_after @ before[r, r] @ G_after.T + R):
            raise Wrong(
                "G is evaluated at the pose after the motion; eq. (7) takes the one before."
            )
        if close(got[r, r], G.T @ before[r, r] @ G + R):
            raise Wrong("Σ[r, r] has G and Gᵀ the wrong way round.")
        mine = _students_G(got, before)
        if mine is None:
            mine = _one_entry_off(got[r, r], before[r, r], G, R)
        if mine is not None and close(got[r, r], mine @ before[r, r] @ mine.T + R):
            entry_verdict(mine, G, "G", POSE_NAMES, POSE_NAMES)
        raise Wrong("Σ[r, r] is wrong.")
    if got.shape[0] > 3:
        if close(got[r, m], before[r, m]):
            raise Wrong("the robot-landmark cross-covariance Σ[r, m] is not updated.")
        if not close(got[r, m], want[r, m]):
            mine = _students_G(got, before)
            if mine is not None:
                entry_verdict(mine, G, "G in Σ[r, m] = G Σ[r, m]", POSE_NAMES, POSE_NAMES)
            raise Wrong("the robot-landmark cross-covariance Σ[r, m] is wrong.")
        if not close(got[m, r], want[m, r]):
            raise Wrong("Σ[m, r] does not match Σ[r, m]ᵀ: Σ must stay symmetric.")


PREDICT_EXERCISE = Exercise(
    "3",
    "predict",
    _predict_cases,
    _judge_predict,
    allowed=lambda: (models.motion, models.motion_jacobian, wrap_angle),  # eq. (6), 2a's G
    keeps=("ekfslam.teaching.symbols", "ekfslam.core.models"),
)


def check_predict(predict: Callable[[Array, Array, Array, Array], object]) -> bool:
    """Exercise 3: `predict(mu (d,), Sigma (d, d), u (3,), R (3, 3)) -> (mu, Sigma)`, eq. (9)
    in block form; it may use the motion model f and its G (`ekfslam.core.models.motion`,
    `motion_jacobian`)."""
    return attempt(PREDICT_EXERCISE, predict)
