"""The lab's exercises on the map: the predicted observation, eqs. (13)-(14) (exercise 4), and
the new landmark, eq. (12) (exercise 5), both in notebook 04; the machinery is
`ekfslam.teaching.verdicts`."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ekfslam.core.models import inverse_observation_jacobians, observation, observation_jacobians
from ekfslam.core.steps import new_landmark_step
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
