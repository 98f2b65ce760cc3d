"""The lab's exercises on the map: the predicted observation, eqs. (13)-(14) (exercise 4), the
new landmark, eq. (12) (exercise 5), both in notebook 04, and the update, eqs. (15)-(16)
(exercise 6, notebook 05: 6a Joseph's form, 6b the update that uses it) and its gate (exercise
7); the machinery is `ekfslam.teaching.verdicts`."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator

import numpy as np

from ekfslam.core import models
from ekfslam.core.filter.config import chi2_2dof_quantile
from ekfslam.core.models import inverse_observation_jacobians, observation, observation_jacobians
from ekfslam.core.steps import new_landmark_step, update_steps
from ekfslam.geometry import wrap_angle
from ekfslam.teaching.verdicts import (
    POSE_NAMES,
    Array,
    Exercise,
    Wrong,
    as_array,
    attempt,
    close,
    entry_verdict,
    evaluate,
)

Q_LAB = np.diag([9e-4, 4e-3])  # (3 cm)², (0.063 rad)²

# --- exercise 4: the predicted observation (eq. 13, atan2) and H (eq. 14) -----------------------


def _observation_cases(rng: np.random.Generator) -> list[dict]:
    """The first landmark lies behind the robot's x (δx < 0), where arctan(δy/δx) is off by π;
    each case also carries its mirror, the landmark moved ahead of the robot (δx > 0), so that a
    bearing off by π there too is told from the seed's arctan."""
    behind = (
        np.array([*rng.uniform(0.1, 0.3, 2) * [1, -1], rng.uniform(2.0, 3.0)]),
        np.array([rng.uniform(-0.75, -0.5), rng.uniform(0.2, 0.5)]),
    )
    ahead = (np.array([*rng.uniform(-0.4, -0.3, 2), 0.0]), rng.uniform(0.3, 0.75, 2))
    # a landmark behind-left of a robot heading behind-right: atan2 - θ lies beyond π, so an
    # unwrapped bearing shows
    heading = -rng.uniform(2.5, 3.0)
    direction = rng.uniform(2.0, 2.8)
    start = rng.uniform(-0.2, 0.2, 2)
    across = (
        np.array([*start, heading]),
        start + rng.uniform(0.5, 1.0) * np.array([np.cos(direction), np.sin(direction)]),
    )
    pairs = [behind, ahead, across] + [
        (rng.uniform([-0.5, -0.5, -np.pi], [0.5, 0.5, np.pi]), rng.uniform(-0.75, 0.75, 2))
        for _ in range(3)
    ]
    cases = []
    for pose, landmark in pairs:
        mirror = landmark.copy()
        mirror[0] = pose[0] + abs(landmark[0] - pose[0])
        case = {"pose": pose, "landmark": landmark, "mirror": mirror}
        case["z"], case["z_mirror"] = observation(pose, landmark), observation(pose, mirror)
        case["H"] = observation_jacobians(pose, landmark)
        cases.append(case)
    return cases


def _check_bearing(got: float, got_mirror: float, case: dict, wrapped: bool) -> None:
    pose, landmark = case["pose"], case["landmark"]
    want, dx, dy = case["z"][1], landmark[0] - pose[0], landmark[1] - pose[1]
    off = wrap_angle(got - want)
    if abs(abs(off) - np.pi) < 1e-6:
        if abs(abs(wrap_angle(got_mirror - case["z_mirror"][1])) - np.pi) < 1e-6:
            raise Wrong(
                "your bearing is off by π wherever the landmark is: it points from the landmark "
                "to the robot. δ is landmark − robot (eq. 13)."
            )
        if dx < 0:
            raise Wrong("your bearing is off by π when the landmark is behind (δx < 0): use atan2.")
    if abs(wrap_angle(got - (np.arctan2(dx, dy) - pose[2]))) < 1e-6 and abs(off) > 1e-6:
        raise Wrong("your bearing is atan2(δx, δy): atan2 takes δy first, atan2(δy, δx).")
    if abs(wrap_angle(got - (np.arctan2(dy, dx) + pose[2]))) < 1e-6 and abs(off) > 1e-6:
        raise Wrong("your bearing adds the heading θ: the bearing is the direction minus θ.")
    if abs(off) > 1e-6 and not close(off, 0.0):
        raise Wrong("the bearing ẑ[1] is wrong (eq. 13).")
    if wrapped and not close(got, want):
        raise Wrong("your bearing is not wrapped to [-π, π).")


def _check_range(got: float, case: dict) -> None:
    want = case["z"][0]
    if close(got, want):
        return
    if close(got, want**2):
        raise Wrong("your range ẑ[0] is the squared distance: take its square root.")
    raise Wrong("the range ẑ[0] is wrong (eq. 13).")


def _judge_observation_model(call: Callable, case: dict) -> None:
    result = call()
    if not isinstance(result, tuple) or len(result) != 3:
        raise Wrong("derive() should return (z_hat, H_pose, H_landmark).")
    z_hat, H_pose, H_landmark = result
    names = ("x", "y", "theta", "m_x", "m_y")
    values = dict(zip(names, [*case["pose"], *case["landmark"]], strict=True))
    mirror = dict(zip(names, [*case["pose"], *case["mirror"]], strict=True))
    got = as_array(evaluate(z_hat, values, "z_hat"), (2,), "z_hat")
    got_mirror = as_array(evaluate(z_hat, mirror, "z_hat"), (2,), "z_hat")
    _check_range(got[0], case)
    _check_bearing(got[1], got_mirror[1], case, wrapped=False)
    want_p, want_l = case["H"]
    got_p = as_array(evaluate(H_pose, values, "H_pose"), (2, 3), "H_pose")
    got_l = as_array(evaluate(H_landmark, values, "H_landmark"), (2, 2), "H_landmark")
    entry_verdict(got_p, want_p, "H_pose", ("r", "φ"), POSE_NAMES)
    entry_verdict(got_l, want_l, "H_landmark", ("r", "φ"), ("μx", "μy"))


OBSERVATION_MODEL_EXERCISE = Exercise(
    "4a",
    "derive_observation",
    _observation_cases,
    _judge_observation_model,
    numeric=False,
    differentiates=True,
    keeps=("ekfslam.teaching.symbols", "ekfslam.core.models"),
    denies=(
        "ekfslam.core.models:observation",
        "ekfslam.core.models:observation_jacobians",
        "ekfslam.core.models:robot_observation",  # eq. (13) again, for a robot's centre
        "ekfslam.core.models:robot_observation_jacobians",
    ),
)


def check_observation_model(derive: Callable[[], tuple[object, object, object]]) -> bool:
    """Exercise 4a: `derive() -> (z_hat, H_pose, H_landmark)`, sympy: ẑ of eq. (13) (2x1) and
    its Jacobians (2x3, 2x2) of eq. (14), derived by sympy, in the symbols x, y, theta, m_x,
    m_y."""
    return attempt(OBSERVATION_MODEL_EXERCISE, derive)


def _judge_predicted_observation(call: Callable, case: dict) -> None:
    pose, landmark = case["pose"], case["landmark"]
    got = as_array(call(("pose", pose), ("landmark", landmark)), (2,), "your ẑ")
    _check_range(got[0], case)
    if not close(got[1], case["z"][1]):
        mirror = as_array(call(("pose", pose), ("landmark", case["mirror"])), (2,), "your ẑ")
        _check_bearing(got[1], mirror[1], case, wrapped=True)


PREDICTED_OBSERVATION_EXERCISE = Exercise(
    "4b",
    "predict_z",
    _observation_cases,
    _judge_predicted_observation,
    allowed=lambda: (wrap_angle,),
    keeps=("ekfslam.teaching.symbols", "ekfslam.core.models"),
    denies=(
        "ekfslam.core.models:observation",
        "ekfslam.core.models:observation_jacobians",
        "ekfslam.core.models:robot_observation",  # eq. (13) again, for a robot's centre
        "ekfslam.core.models:robot_observation_jacobians",
    ),
)


def check_predicted_observation(predict_z: Callable[[Array, Array], object]) -> bool:
    """Exercise 4b: `predict_z(pose (3,), landmark (2,)) -> (r, φ)`, eq. (13) in numpy, the
    bearing wrapped to [-π, π)."""
    return attempt(PREDICTED_OBSERVATION_EXERCISE, predict_z)


# --- exercise 5: the new landmark, eq. (12), with its cross-covariance --------------------------


def _new_landmark_cases(rng: np.random.Generator) -> list[dict]:
    cases = []
    for n in (0, 1, 3):
        d = 3 + 2 * n
        mu = np.concatenate(
            [[*rng.uniform(-0.5, 0.5, 2), rng.uniform(-3, 3)], rng.normal(size=2 * n)]
        )
        A = rng.normal(size=(d, d))
        Sigma = 1e-3 * (A @ A.T + np.eye(d))
        z = np.array([rng.uniform(0.3, 1.2), rng.uniform(-1.5, 1.5)])
        want = new_landmark_step(mu, Sigma, z, Q_LAB)
        cases.append({"mu": mu, "Sigma": Sigma, "z": z, "Q": Q_LAB.copy(), "want": want})
    return cases


def _judge_new_landmark(call: Callable, case: dict) -> None:
    mu, Sigma, z, Q = case["mu"], case["Sigma"], case["z"], case["Q"]
    d, n = mu.size, (mu.size - 3) // 2
    result = call(("μ", mu), ("Σ", Sigma), ("z", z), ("Q", Q))
    if not isinstance(result, tuple | list) or len(result) != 2:
        raise Wrong("add_landmark should return the pair (mu, Sigma).")
    what = f"(with {n} landmarks before)"
    got_mu = as_array(result[0], (d + 2,), f"mu {what}")
    got = as_array(result[1], (d + 2, d + 2), f"Sigma {what}")
    want_mu, want = case["want"]
    _check_new_landmark(got_mu, got, want_mu, want, mu, Sigma, z, Q)


def _check_new_landmark(
    got_mu: Array, got: Array, want_mu: Array, want: Array, mu: Array, Sigma: Array, z, Q
) -> None:
    d, r, l = mu.size, slice(0, 3), slice(mu.size, mu.size + 2)
    if not close(got_mu[:d], mu) or not close(got[:d, :d], Sigma):
        raise Wrong("the old state changed: adding a landmark only appends rows and columns.")
    if not close(got_mu[d:], want_mu[d:]):
        raise Wrong(
            "the new landmark's position is wrong (eq. 12: the bearing is from the heading)."
        )
    G_p, G_z = inverse_observation_jacobians(mu[r], z)
    if not close(got[l, l], want[l, l]):
        if close(got[l, l], G_z @ Q @ G_z.T):
            raise Wrong("the new landmark's covariance ignores the robot's uncertainty.")
        if close(got[l, l], G_p @ Sigma[r, r] @ G_p.T):
            raise Wrong("the new landmark's covariance ignores the measurement noise Q.")
        raise Wrong("the new landmark's covariance Σ[l, l] is wrong.")
    if close(got[l, :d], 0.0):
        raise Wrong("the cross-covariance of the new landmark is missing.")
    if not close(got[l, r], want[l, r]):
        raise Wrong("the cross-covariance of the new landmark with the robot, Σ[l, r], is wrong.")
    if not close(got[l, :d], want[l, :d]):
        raise Wrong(
            "the new landmark's cross-covariance with the older landmarks is missing or wrong."
        )
    if not close(got[:d, l], got[l, :d].T):
        raise Wrong("Σ[:, l] does not match Σ[l, :]ᵀ: Σ must stay symmetric.")


NEW_LANDMARK_EXERCISE = Exercise(
    "5",
    "add_landmark",
    _new_landmark_cases,
    _judge_new_landmark,
    allowed=lambda: (models.inverse_observation, models.inverse_observation_jacobians, wrap_angle),
    keeps=("ekfslam.teaching.symbols", "ekfslam.core.models"),
)


def check_new_landmark(add_landmark: Callable[[Array, Array, Array, Array], object]) -> bool:
    """Exercise 5: `add_landmark(mu (d,), Sigma (d, d), z (2,), Q (2, 2)) -> (mu, Sigma)` of
    size d + 2; it may use eq. (12) and its Jacobians (`models.inverse_observation`,
    `models.inverse_observation_jacobians`)."""
    return attempt(NEW_LANDMARK_EXERCISE, add_landmark)


# --- exercise 6: the update, eqs. (15)-(16), bearing innovation wrapped, Joseph's form ----------


def _joseph_cases(rng: np.random.Generator) -> list[dict]:
    """Gains that are not eq. (15)'s, where (I - KH)Σ and Joseph's form part by much more than
    rounding (1.2 K; K on the robot's and the seen landmark's rows only, the shortcut of notebook
    05; a random gain), on states of 1-3 landmarks."""
    cases = []
    for n, j in ((1, 0), (2, 1), (3, 2)):
        d = 3 + 2 * n
        A = rng.normal(size=(d, d))
        Sigma = 1e-3 * (A @ A.T + np.eye(d))
        H = np.zeros((2, d))
        H[:, :3], H[:, 3 + 2 * j : 5 + 2 * j] = rng.normal(size=(2, 3)), rng.normal(size=(2, 2))
        K = Sigma @ H.T @ np.linalg.inv(H @ Sigma @ H.T + Q_LAB)  # eq. (15)
        rows = np.zeros((d, 1))
        rows[:3] = rows[3 + 2 * j : 5 + 2 * j] = 1.0
        gains = {"1.2 K": 1.2 * K, "K on the robot and the seen landmark only": rows * K}
        gains["a random gain"] = rng.normal(0, 0.5, (d, 2))
        for name, G in gains.items():
            I_KH = np.eye(d) - G @ H
            want = I_KH @ Sigma @ I_KH.T + G @ Q_LAB @ G.T
            cases.append({"gain": name, "Sigma": Sigma, "K": G, "H": H, "Q": Q_LAB.copy()})
            cases[-1]["want"] = want
    return cases


def _judge_joseph(call: Callable, case: dict) -> None:
    gain, Sigma, K, H, Q = (case[k] for k in ("gain", "Sigma", "K", "H", "Q"))
    d = len(Sigma)
    got = as_array(call(("Σ", Sigma), ("K", K), ("H", H), ("Q", Q)), (d, d), f"your Σ ({gain})")
    if close(got, case["want"], atol=1e-12):
        return
    I_KH = np.eye(d) - K @ H
    if close(got, I_KH @ Sigma, atol=1e-12):
        raise Wrong(
            f"that is the seed's (I - KH)Σ, which is right only for the optimal gain of eq. (15); "
            f"with {gain} it is not the covariance of μ + Kν."
        )
    if close(got, I_KH @ Sigma @ I_KH.T, atol=1e-12):
        raise Wrong("the measurement noise's share K Q Kᵀ is missing.")
    if close(got, I_KH.T @ Sigma @ I_KH + K @ Q @ K.T, atol=1e-12):
        raise Wrong("the transposes are on the wrong side: (I - KH) comes first.")
    if close(got, I_KH @ Sigma @ I_KH.T + K @ K.T, atol=1e-12):
        raise Wrong("the noise term is K Q Kᵀ: Q is missing from it.")
    if not close(got, got.T, atol=1e-12):
        raise Wrong(f"your Σ is not symmetric (with {gain}).")
    raise Wrong(f"your Σ is wrong with {gain} (Joseph's form holds for any gain).")


JOSEPH_EXERCISE = Exercise(
    "6a", "joseph", _joseph_cases, _judge_joseph, keeps=("ekfslam.core.models",)
)


def check_joseph(joseph: Callable[[Array, Array, Array, Array], object]) -> bool:
    """Exercise 6a: `joseph(Sigma (d, d), K (d, 2), H (2, d), Q (2, 2)) -> Sigma (d, d)`, the
    covariance after an update with the gain K in Joseph's form, (I - KH) Σ (I - KH)ᵀ + K Q Kᵀ
    (eq. 16 done right). It is tried with gains that are not the optimal one of eq. (15), where
    the seed's (I - KH)Σ is wrong, so that form does not pass."""
    return attempt(JOSEPH_EXERCISE, joseph)


def _update_cases(rng: np.random.Generator) -> list[dict]:
    """(mu, Sigma, j, z, Q); the first sees its landmark right behind the robot, where ẑ's
    bearing is near +π and z's near -π, so an unwrapped innovation is off by 2π; the last has
    the heading just below π and a sighting that turns it across, so an unwrapped posterior
    heading shows; two have a landmark after the seen one, so an update of the next slot shows."""
    cases = []
    for n, j in ((1, 0), (2, 1), (3, 1), (3, 0), (2, 0)):
        d = 3 + 2 * n
        mu = np.concatenate(
            [[*rng.uniform(-0.3, 0.3, 2), rng.uniform(-3, 3)], rng.normal(size=2 * n)]
        )
        A = rng.normal(size=(d, d))
        Sigma = 1e-3 * (A @ A.T + np.eye(d))
        z = observation(mu[:3], mu[3 + 2 * j : 5 + 2 * j]) + rng.normal(0, [0.03, 0.05])
        z[1] = wrap_angle(float(z[1]))
        cases.append([mu, Sigma, j, z])
    mu, _, _, _ = cases[0]
    mu[:3] = [*rng.uniform(-0.05, 0.05, 2), 0.0]
    mu[3:5] = mu[:2] + np.array([-1.0, rng.uniform(0.001, 0.003)])  # bearing just below π
    cases[0][3] = np.array([1.02, wrap_angle(np.pi + rng.uniform(0.003, 0.006))])
    mu, Sigma, j, z = cases[-1]
    mu[2] = np.pi - 1e-3
    truth = observation(mu[:3], mu[3 + 2 * j : 5 + 2 * j])
    for _ in range(100):  # a Σ whose heading no bearing turns past π is drawn again
        steps = np.linspace(0.02, 0.3, 15)  # a bearing that turns the heading past π
        z = next(
            (z for t in steps if (z := _turning_past_pi(mu, Sigma, j, truth, t)) is not None), None
        )
        if z is not None:
            break
        A = rng.normal(size=Sigma.shape)
        Sigma = 1e-3 * (A @ A.T + np.eye(len(Sigma)))
    else:
        raise RuntimeError("no sighting turns the heading past π: the cases cannot be drawn")
    cases[-1][1], cases[-1][3] = Sigma, z
    out = []
    for mu, Sigma, j, z in cases:
        s = update_steps(mu, Sigma, j, z, Q_LAB)
        out.append({"mu": mu, "Sigma": Sigma, "j": j, "z": z, "Q": Q_LAB.copy()})
        out[-1]["want"] = (s.mu_post, s.Sigma_joseph)
        out[-1]["unwrapped"] = s.mu_prior + s.K @ (z - s.z_hat)
    return out


def _turning_past_pi(mu: Array, Sigma: Array, j: int, truth: Array, step: float) -> Array | None:
    """A sighting `step` rad off `truth` whose update turns the heading past π, or None."""
    for sign in (1.0, -1.0):
        z = truth + np.array([0.0, sign * step])
        z[1] = wrap_angle(float(z[1]))
        s = update_steps(mu, Sigma, j, z, Q_LAB)
        if (s.mu_prior + s.K @ s.nu)[2] > np.pi + 1e-3:
            return z
    return None


def _update_at(mu: Array, Sigma: Array, row: int, z: Array, Q: Array) -> Array:
    """The posterior mean of eqs. (13)-(16) with the landmark read from rows row, row + 1."""
    d, r, l = mu.size, slice(0, 3), slice(row, row + 2)
    H = np.zeros((2, d))
    H[:, r], H[:, l] = observation_jacobians(mu[r], mu[l])
    K = Sigma @ H.T @ np.linalg.inv(H @ Sigma @ H.T + Q)
    nu = z - observation(mu[r], mu[l])
    nu[1] = wrap_angle(float(nu[1]))
    post = mu + K @ nu
    post[2] = wrap_angle(float(post[2]))
    return post


def _judge_update(call: Callable, case: dict) -> None:
    mu, Sigma, j, z, Q = (case[k] for k in ("mu", "Sigma", "j", "z", "Q"))
    d = mu.size
    result = call(("μ", mu), ("Σ", Sigma), ("j", j), ("z", z), ("Q", Q))
    if not isinstance(result, tuple | list) or len(result) != 2:
        raise Wrong("update should return the pair (mu, Sigma).")
    got_mu = as_array(result[0], (d,), "mu")
    got = as_array(result[1], (d, d), "Sigma")
    want_mu, want = case["want"]
    if not close(got_mu, want_mu):
        _diagnose_posterior_mean(got_mu, case)
    if not close(got, want):
        if close(got, Sigma):
            raise Wrong("Σ is not updated.")
        if not close(got, got.T):
            raise Wrong("your posterior Σ is not symmetric.")
        raise Wrong("the posterior covariance is wrong (eq. 16, Joseph's form).")


def _diagnose_posterior_mean(got_mu: Array, case: dict) -> None:
    mu, Sigma, j, z, Q = (case[k] for k in ("mu", "Sigma", "j", "z", "Q"))
    want_mu, d = case["want"][0], mu.size
    if close(got_mu[3:], case["unwrapped"][3:]) and not close(got_mu[3:], want_mu[3:]):
        raise Wrong(
            "your bearing innovation z - ẑ is not wrapped (the seed forgets it too): behind the "
            "robot it is off by 2π."
        )
    if close(wrap_angle(float(got_mu[2])), want_mu[2]) and close(got_mu[3:], want_mu[3:]):
        raise Wrong("your posterior heading is not wrapped to [-π, π).")
    for row in range(2, d - 1):
        if row != 3 + 2 * j and close(got_mu, _update_at(mu, Sigma, row, z, Q)):
            raise Wrong(
                f"your update reads the landmark from rows {row}, {row + 1} of μ; slot {j} is "
                "3 + 2j and 4 + 2j (eq. 1: three robot rows, then two per landmark)."
            )
    if close(got_mu, _update_at(mu, Sigma, 3 + 2 * j, z, 0 * Q)):
        raise Wrong("the measurement noise Q is missing from S = H Σ Hᵀ + Q.")
    raise Wrong("the posterior mean is wrong (eqs. 15-16).")


class _WatchedJoseph:
    """The student's `joseph` as their update sees it during exercise 6b: counted, and a stub
    told apart (the class is on 6b's allowlist: it is the check's, not the package's answer)."""

    def __init__(self, joseph: Callable) -> None:
        self.joseph, self.calls = joseph, 0

    def __call__(self, *args, **kwargs):
        self.calls += 1
        try:
            return self.joseph(*args, **kwargs)
        except NotImplementedError:
            raise Wrong("your update calls joseph, and exercise 6a is not done yet.") from None


@contextlib.contextmanager
def _watching_joseph(update: Callable) -> Iterator[None]:
    """While the cases run, the `joseph` that `update` would call (a notebook's global) is
    counted; an update that never calls it is told so."""
    names = getattr(update, "__globals__", {})
    joseph = names.get("joseph")
    if not callable(joseph):
        yield
        return
    watched = _WatchedJoseph(joseph)
    names["joseph"] = watched
    try:
        yield
    finally:
        names["joseph"] = joseph
    if watched.calls == 0:
        raise Wrong("your update does not call your joseph(Sigma, K, H, Q) of exercise 6a for Σ.")


UPDATE_EXERCISE = Exercise(
    "6b",
    "update",
    _update_cases,
    _judge_update,
    allowed=lambda: (models.observation, models.observation_jacobians, wrap_angle, _WatchedJoseph),
    session=_watching_joseph,
    watches="joseph",
    keeps=("ekfslam.core.models",),
)


def check_update(update: Callable[[Array, Array, int, Array, Array], object]) -> bool:
    """Exercise 6b: `update(mu (d,), Sigma (d, d), j, z (2,), Q (2, 2)) -> (mu, Sigma)`, one
    correction with landmark slot j, eqs. (13)-(16), its Σ from the student's `joseph` of
    exercise 6a; it may use eqs. (13)-(14) (`models.observation`, `observation_jacobians`).
    With the optimal gain Joseph's form and (I - KH)Σ agree, so the form is 6a's check; here a
    `joseph` in the update's module is watched, and an update that never calls it is told so."""
    return attempt(UPDATE_EXERCISE, update)


# --- exercise 7: the NIS gate, νᵀ S⁻¹ ν against the chi-square quantile of 2 dof ---------------


def _gate_cases(rng: np.random.Generator) -> list[dict]:
    """(z, ẑ, S, p); the first sees its tag right behind the robot (ẑ's bearing near +π, z's
    near -π), and every S has a large off-diagonal term, so dropping it or not inverting S shows."""
    behind = np.array([rng.uniform(0.8, 1.2), -np.pi + rng.uniform(0.002, 0.006)])
    z_hat_behind = np.array(
        [behind[0] - rng.uniform(0.01, 0.03), np.pi - rng.uniform(0.001, 0.003)]
    )
    raw = [(behind, z_hat_behind, rng.choice([0.99, 0.95]))]
    raw += [(rng.uniform([0.3, -np.pi], [1.5, np.pi]), None, p) for p in (0.95, 0.999, 0.5)]
    cases = []
    for z, z_hat, p in raw:
        if z_hat is None:
            z_hat = z + rng.normal(0, [0.04, 0.06])
            z_hat[1] = wrap_angle(float(z_hat[1]))
        A = rng.normal(size=(2, 2)) * [[0.03, 0.0], [0.02, 0.05]]
        S = A @ A.T + np.diag([4e-4, 1e-3])
        nu = z - z_hat
        nu[1] = wrap_angle(float(nu[1]))
        cases.append({"z": z, "z_hat": z_hat, "S": S, "p": float(p)})
        cases[-1]["want"] = (float(nu @ np.linalg.solve(S, nu)), chi2_2dof_quantile(float(p)))
    return cases


def _judge_nis_gate(call: Callable, case: dict) -> None:
    z, z_hat, S, p = (case[k] for k in ("z", "z_hat", "S", "p"))
    result = call(("z", z), ("ẑ", z_hat), ("S", S), ("p", p))
    if not isinstance(result, tuple | list) or len(result) != 2:
        raise Wrong("nis_gate should return the pair (nis, threshold).")
    nis, threshold = (
        float(as_array(v, (), w)) for v, w in zip(result, ("nis", "threshold"), strict=True)
    )
    want, want_gate = case["want"]
    nu = z - z_hat
    raw = nu.copy()
    nu[1] = wrap_angle(float(nu[1]))
    if not close(nis, want):
        if close(nis, raw @ np.linalg.solve(S, raw)):
            raise Wrong(
                "your innovation's bearing is not wrapped: behind the robot ν is off by 2π."
            )
        if close(nis, nu @ S @ nu):
            raise Wrong("your NIS multiplies by S: it divides by it, νᵀ S⁻¹ ν.")
        if close(nis, float(np.sum(nu**2 / np.diag(S)))):
            raise Wrong("your NIS ignores the off-diagonal of S: use all of S⁻¹.")
        if close(nis, np.sqrt(want)):
            raise Wrong("the NIS is the squared Mahalanobis distance: no square root.")
        raise Wrong("the NIS is wrong.")
    if not close(threshold, want_gate):
        if close(threshold, -2.0 * np.log(p)):
            raise Wrong(f"your threshold at p = {p} uses ln p; the tail is 1 - p.")
        if close(threshold, np.sqrt(want_gate)):
            raise Wrong("your threshold is a distance; the NIS is a squared one.")
        raise Wrong(f"your threshold at p = {p} is not the 2-dof chi-square quantile.")


NIS_GATE_EXERCISE = Exercise(
    "7",
    "nis_gate",
    _gate_cases,
    _judge_nis_gate,
    allowed=lambda: (wrap_angle,),
    keeps=("ekfslam.core.models",),
)


def check_nis_gate(nis_gate: Callable[[Array, Array, Array, float], object]) -> bool:
    """Exercise 7: `nis_gate(z (2,), z_hat (2,), S (2, 2), p) -> (nis, threshold)`: the NIS
    νᵀ S⁻¹ ν of the innovation ν = z - ẑ (bearing wrapped, eq. 13) and the chi-square quantile
    of 2 degrees of freedom at probability p, -2 ln(1 - p) (the filter accepts when
    nis <= threshold)."""
    return attempt(NIS_GATE_EXERCISE, nis_gate)
