"""The lab's exercises on the map: the predicted observation, eqs. (13)-(14) (exercise 4), the
new landmark, eq. (12) (exercise 5), both in notebook 04, and the update, eqs. (15)-(16)
(exercise 6, notebook 05: 6a Joseph's form, 6b the update that uses it); the machinery is
`ekfslam.teaching.verdicts`."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ekfslam.core.models import inverse_observation_jacobians, observation, observation_jacobians
from ekfslam.core.steps import new_landmark_step, update_steps
from ekfslam.geometry import wrap_angle
from ekfslam.teaching.verdicts import (
    POSE_NAMES,
    RNG_SEED,
    Array,
    Wrong,
    as_array,
    attempt,
    close,
    entry_verdict,
    evaluate,
)

# --- exercise 4: the predicted observation (eq. 13, atan2) and H (eq. 14) -----------------------


def _poses_and_landmarks() -> list[tuple[Array, Array]]:
    """The first landmark is behind the robot's x (δx < 0), where arctan(δy/δx) is off by π."""
    rng = np.random.default_rng(RNG_SEED)
    fixed = [(np.array([0.2, -0.1, 2.5]), np.array([-0.75, 0.375]))]
    fixed.append((np.array([-0.375, -0.375, 0.0]), np.array([0.375, 0.75])))
    return fixed + [
        (rng.uniform([-0.5, -0.5, -np.pi], [0.5, 0.5, np.pi]), rng.uniform(-0.75, 0.75, 2))
        for _ in range(4)
    ]


def _check_bearing(got: float, want: float, dx: float, wrapped: bool) -> None:
    off = wrap_angle(got - want)
    if abs(abs(off) - np.pi) < 1e-6 and dx < 0:
        raise Wrong("your bearing is off by π when the landmark is behind (δx < 0): use atan2.")
    if abs(off) > 1e-9:
        raise Wrong("the bearing ẑ[1] is wrong (eq. 13).")
    if wrapped and not close(got, want):
        raise Wrong("your bearing is not wrapped to [-π, π).")


def check_observation_model(derive: Callable[[], tuple[object, object, object]]) -> bool:
    """Exercise 4a: `derive() -> (z_hat, H_pose, H_landmark)`, sympy: ẑ of eq. (13) (2x1) and
    its Jacobians (2x3, 2x2) of eq. (14), in the symbols x, y, theta, m_x, m_y."""

    def check() -> None:
        result = derive()
        if not isinstance(result, tuple) or len(result) != 3:
            raise Wrong("derive() should return (z_hat, H_pose, H_landmark).")
        z_hat, H_pose, H_landmark = result
        for pose, landmark in _poses_and_landmarks():
            values = dict(zip(("x", "y", "theta", "m_x", "m_y"), [*pose, *landmark], strict=True))
            got = evaluate(z_hat, values, "z_hat").reshape(-1)
            want = observation(pose, landmark)
            as_array(got, (2,), "z_hat")
            if not close(got[0], want[0]):
                raise Wrong("the range ẑ[0] is wrong (eq. 13).")
            _check_bearing(got[1], want[1], landmark[0] - pose[0], wrapped=False)
            want_p, want_l = observation_jacobians(pose, landmark)
            got_p = as_array(evaluate(H_pose, values, "H_pose"), (2, 3), "H_pose")
            got_l = as_array(evaluate(H_landmark, values, "H_landmark"), (2, 2), "H_landmark")
            entry_verdict(got_p, want_p, "H_pose", ("r", "φ"), POSE_NAMES)
            entry_verdict(got_l, want_l, "H_landmark", ("r", "φ"), ("μx", "μy"))

    return attempt("4a", check)


def check_predicted_observation(predict_z: Callable[[Array, Array], object]) -> bool:
    """Exercise 4b: `predict_z(pose (3,), landmark (2,)) -> (r, φ)`, eq. (13) in numpy, the
    bearing wrapped to [-π, π) (the answer is `ekfslam.core.models.observation`)."""

    def check() -> None:
        for pose, landmark in _poses_and_landmarks():
            got = as_array(predict_z(pose.copy(), landmark.copy()), (2,), "your ẑ")
            want = observation(pose, landmark)
            if not close(got[0], want[0]):
                raise Wrong("the range ẑ[0] is wrong (eq. 13).")
            _check_bearing(got[1], want[1], landmark[0] - pose[0], wrapped=True)

    return attempt("4b", check)


# --- exercise 5: the new landmark, eq. (12), with its cross-covariance --------------------------


def check_new_landmark(add_landmark: Callable[[Array, Array, Array, Array], object]) -> bool:
    """Exercise 5: `add_landmark(mu (d,), Sigma (d, d), z (2,), Q (2, 2)) -> (mu, Sigma)` of
    size d + 2 (the answer is `ekfslam.core.steps.new_landmark_step`)."""

    def check() -> None:
        rng = np.random.default_rng(RNG_SEED)
        for n in (0, 1, 3):
            d = 3 + 2 * n
            mu = np.concatenate(
                [[*rng.uniform(-0.5, 0.5, 2), rng.uniform(-3, 3)], rng.normal(size=2 * n)]
            )
            A = rng.normal(size=(d, d))
            Sigma = 1e-3 * (A @ A.T + np.eye(d))
            z, Q = np.array([rng.uniform(0.3, 1.2), rng.uniform(-1.5, 1.5)]), np.diag([9e-4, 4e-3])
            result = add_landmark(mu.copy(), Sigma.copy(), z.copy(), Q.copy())
            if not isinstance(result, tuple) or len(result) != 2:
                raise Wrong("add_landmark should return the pair (mu, Sigma).")
            what = f"(with {n} landmarks before)"
            got_mu = as_array(result[0], (d + 2,), f"mu {what}")
            got = as_array(result[1], (d + 2, d + 2), f"Sigma {what}")
            want_mu, want = new_landmark_step(mu, Sigma, z, Q)
            _check_new_landmark(got_mu, got, want_mu, want, mu, Sigma, z, Q)

    return attempt("5", check)


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


# --- exercise 6: the update, eqs. (15)-(16), bearing innovation wrapped, Joseph's form ----------


def _joseph_cases(rng: np.random.Generator) -> list[tuple[str, Array, Array, Array, Array]]:
    """(gain, Sigma, K, H, Q): gains that are not eq. (15)'s, where (I - KH)Σ and Joseph's form
    part by much more than rounding (1.2 K; K on the robot's and the seen landmark's rows only,
    the shortcut of notebook 05; a random gain), on states of 1-3 landmarks."""
    Q = np.diag([9e-4, 4e-3])
    cases = []
    for n, j in ((1, 0), (2, 1), (3, 2)):
        d = 3 + 2 * n
        A = rng.normal(size=(d, d))
        Sigma = 1e-3 * (A @ A.T + np.eye(d))
        H = np.zeros((2, d))
        H[:, :3], H[:, 3 + 2 * j : 5 + 2 * j] = rng.normal(size=(2, 3)), rng.normal(size=(2, 2))
        K = Sigma @ H.T @ np.linalg.inv(H @ Sigma @ H.T + Q)  # eq. (15)
        rows = np.zeros((d, 1))
        rows[:3] = rows[3 + 2 * j : 5 + 2 * j] = 1.0
        gains = {"1.2 K": 1.2 * K, "K on the robot and the seen landmark only": rows * K}
        gains["a random gain"] = rng.normal(0, 0.5, (d, 2))
        cases += [(name, Sigma, G, H, Q) for name, G in gains.items()]
    return cases


def check_joseph(joseph: Callable[[Array, Array, Array, Array], object]) -> bool:
    """Exercise 6a: `joseph(Sigma (d, d), K (d, 2), H (2, d), Q (2, 2)) -> Sigma (d, d)`, the
    covariance after an update with the gain K in Joseph's form, (I - KH) Σ (I - KH)ᵀ + K Q Kᵀ
    (eq. 16 done right; `ekfslam.core.steps.update_steps` computes it as `Sigma_joseph`). It is
    tried with gains that are not the optimal one of eq. (15), where the seed's (I - KH)Σ is
    wrong, so that form does not pass."""

    def check() -> None:
        for gain, Sigma, K, H, Q in _joseph_cases(np.random.default_rng(RNG_SEED)):
            d = len(Sigma)
            got = joseph(Sigma.copy(), K.copy(), H.copy(), Q.copy())
            got = as_array(got, (d, d), f"your Σ (with {gain})")
            I_KH = np.eye(d) - K @ H
            want = I_KH @ Sigma @ I_KH.T + K @ Q @ K.T
            if close(got, want, atol=1e-12):
                continue
            if close(got, I_KH @ Sigma, atol=1e-12):
                raise Wrong(
                    f"that is the seed's (I - KH)Σ, which is right only for the optimal gain of "
                    f"eq. (15); with {gain} it is not the covariance of μ + Kν."
                )
            if close(got, I_KH @ Sigma @ I_KH.T, atol=1e-12):
                raise Wrong("the measurement noise's share K Q Kᵀ is missing.")
            if close(got, I_KH.T @ Sigma @ I_KH + K @ Q @ K.T, atol=1e-12):
                raise Wrong("the transposes are on the wrong side: (I - KH) comes first.")
            if not close(got, got.T, atol=1e-12):
                raise Wrong(f"your Σ is not symmetric (with {gain}).")
            raise Wrong(f"your Σ is wrong with {gain} (Joseph's form holds for any gain).")

    return attempt("6a", check)


def _update_cases(rng: np.random.Generator) -> list[tuple[Array, Array, int, Array, Array]]:
    """(mu, Sigma, j, z, Q); the first sees its landmark right behind the robot, where ẑ's
    bearing is near +π and z's near -π, so an unwrapped innovation is off by 2π."""
    Q = np.diag([9e-4, 4e-3])
    cases = []
    for n, j in ((1, 0), (2, 1), (3, 1)):
        d = 3 + 2 * n
        mu = np.concatenate(
            [[*rng.uniform(-0.3, 0.3, 2), rng.uniform(-3, 3)], rng.normal(size=2 * n)]
        )
        A = rng.normal(size=(d, d))
        Sigma = 1e-3 * (A @ A.T + np.eye(d))
        z = observation(mu[:3], mu[3 + 2 * j : 5 + 2 * j]) + rng.normal(0, [0.03, 0.05])
        z[1] = wrap_angle(float(z[1]))
        cases.append((mu, Sigma, j, z, Q))
    mu, Sigma, j, _, Q = cases[0]
    mu[:3], mu[3:5] = [0.0, 0.0, 0.0], [-1.0, 0.002]  # bearing π - 0.002
    cases[0] = (mu, Sigma, j, np.array([1.02, wrap_angle(np.pi + 0.004)]), Q)
    return cases


def check_update(update: Callable[[Array, Array, int, Array, Array], object]) -> bool:
    """Exercise 6b: `update(mu (d,), Sigma (d, d), j, z (2,), Q (2, 2)) -> (mu, Sigma)`, one
    correction with landmark slot j, eqs. (13)-(16), its Σ from the student's `joseph` of
    exercise 6a (the answer is `ekfslam.core.steps.update_steps`: its mu_post and Sigma_joseph).
    With the optimal gain Joseph's form and (I - KH)Σ agree, so the form is 6a's check; here a
    `joseph` in the update's module is watched, and an update that never calls it is told so."""

    def check() -> None:
        for mu, Sigma, j, z, Q in _update_cases(np.random.default_rng(RNG_SEED)):
            d = mu.size
            result = update(mu.copy(), Sigma.copy(), j, z.copy(), Q.copy())
            if not isinstance(result, tuple) or len(result) != 2:
                raise Wrong("update should return the pair (mu, Sigma).")
            got_mu = as_array(result[0], (d,), "mu")
            got = as_array(result[1], (d, d), "Sigma")
            want = update_steps(mu, Sigma, j, z, Q)
            unwrapped = want.mu_prior + want.K @ (z - want.z_hat)
            if not close(got_mu, want.mu_post):
                if close(got_mu[3:], unwrapped[3:]):
                    raise Wrong(
                        "your bearing innovation z - ẑ is not wrapped (the seed forgets "
                        "it too): behind the robot it is off by 2π."
                    )
                if close(wrap_angle(float(got_mu[2])), want.mu_post[2]) and close(
                    got_mu[3:], want.mu_post[3:]
                ):
                    raise Wrong("your heading is not wrapped to [-π, π).")
                others = [k for k in range((d - 3) // 2) if k != j]
                if others and close(got_mu, update_steps(mu, Sigma, others[0], z, Q).mu_post):
                    raise Wrong(
                        f"you updated another landmark: slot {j} is rows {3 + 2 * j}, {4 + 2 * j}."
                    )
                if close(got_mu, update_steps(mu, Sigma, j, z, 0 * Q).mu_post):
                    raise Wrong("the measurement noise Q is missing from S = H Σ Hᵀ + Q.")
                raise Wrong("the posterior mean is wrong (eqs. 15-16).")
            if not close(got, want.Sigma_joseph):
                if close(got, Sigma):
                    raise Wrong("Σ is not updated.")
                if not close(got, got.T):
                    raise Wrong("your posterior Σ is not symmetric.")
                raise Wrong("the posterior covariance is wrong (eq. 16, Joseph's form).")

    return attempt("6b", lambda: _watching_joseph(update, check))


def _watching_joseph(update: Callable, check: Callable[[], None]) -> None:
    """Run `check` with the `joseph` that `update` would call (a notebook's global) counted."""
    names = getattr(update, "__globals__", {})
    joseph = names.get("joseph")
    if not callable(joseph):
        return check()
    calls = []

    def watched(*args, **kwargs):
        calls.append(1)
        try:
            return joseph(*args, **kwargs)
        except NotImplementedError:
            raise Wrong("your update calls joseph, and exercise 6a is not done yet.") from None

    names["joseph"] = watched
    try:
        check()
    finally:
        names["joseph"] = joseph
    if not calls:
        raise Wrong("your update does not call your joseph(Sigma, K, H, Q) of exercise 6a for Σ.")


# --- exercise 7: the NIS gate, νᵀ S⁻¹ ν against the chi-square quantile of 2 dof ---------------


def _gate_cases(rng: np.random.Generator) -> list[tuple[Array, Array, Array, float]]:
    """(z, ẑ, S, p); the first sees its tag right behind the robot (ẑ's bearing near +π, z's
    near -π), and every S has a large off-diagonal term, so dropping it or not inverting S shows."""
    cases = [(np.array([1.02, -np.pi + 0.004]), np.array([1.0, np.pi - 0.002]), None, 0.99)]
    cases += [(rng.uniform([0.3, -np.pi], [1.5, np.pi]), None, None, p) for p in (0.95, 0.999, 0.5)]
    out = []
    for z, z_hat, _, p in cases:
        if z_hat is None:
            z_hat = z + rng.normal(0, [0.04, 0.06])
            z_hat[1] = wrap_angle(float(z_hat[1]))
        A = rng.normal(size=(2, 2)) * [[0.03, 0.0], [0.02, 0.05]]
        out.append((z, z_hat, A @ A.T + np.diag([4e-4, 1e-3]), p))
    return out


def check_nis_gate(nis_gate: Callable[[Array, Array, Array, float], object]) -> bool:
    """Exercise 7: `nis_gate(z (2,), z_hat (2,), S (2, 2), p) -> (nis, threshold)`: the NIS
    νᵀ S⁻¹ ν of the innovation ν = z - ẑ (bearing wrapped, eq. 13) and the chi-square quantile
    of 2 degrees of freedom at probability p, -2 ln(1 - p) (the answer is
    `ekfslam.core.filter.config.chi2_2dof_quantile`; the filter accepts when nis <= threshold)."""

    def check() -> None:
        for z, z_hat, S, p in _gate_cases(np.random.default_rng(RNG_SEED)):
            result = nis_gate(z.copy(), z_hat.copy(), S.copy(), p)
            if not isinstance(result, tuple) or len(result) != 2:
                raise Wrong("nis_gate should return the pair (nis, threshold).")
            nis, threshold = (
                float(as_array(v, (), w)) for v, w in zip(result, ("nis", "threshold"), strict=True)
            )
            nu = z - z_hat
            raw = nu.copy()
            nu[1] = wrap_angle(float(nu[1]))
            want = float(nu @ np.linalg.solve(S, nu))
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
            want_gate = -2.0 * np.log1p(-p)
            if not close(threshold, want_gate):
                if close(threshold, -2.0 * np.log(p)):
                    raise Wrong(f"your threshold at p = {p} uses ln p; the tail is 1 - p.")
                if close(threshold, np.sqrt(want_gate)):
                    raise Wrong("your threshold is a distance; the NIS is a squared one.")
                raise Wrong(f"your threshold at p = {p} is not the 2-dof chi-square quantile.")

    return attempt("7", check)
