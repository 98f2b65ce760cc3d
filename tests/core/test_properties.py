"""Property-based tests (hypothesis): Σ stays a covariance whatever valid data the filter gets.

Hypothesis draws the *kind* of run (filter options, noise levels, how many landmarks, how wild
the controls and observations are, a seed); numpy draws the thousands of steps from that seed,
so one example is a whole run and shrinking still names a reproducible case. The 10^5-step run
is a benchmark, not a test: ``python -m studies consistency long-run``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st

from ekfslam import EKFSLAM, FilterConfig
from ekfslam.core.filter.history import Outcome
from ekfslam.core.models import MIN_RANGE_SQUARED, motion_noise
from ekfslam.geometry import wrap_angle

FLOOR = -1e-9  # smallest eigenvalue of Σ allowed, as a fraction of its trace

configs = st.builds(
    FilterConfig,
    init=st.sampled_from(["inverse", "seed"]),
    linearization=st.sampled_from(["standard", "fej", "invariant"]),
    gate=st.sampled_from([None, 9.21, 25.0]),
    gate_after=st.integers(1, 3),
    initial_capacity=st.integers(1, 4),  # exercise the storage doubling too
).filter(lambda c: not (c.linearization == "fej" and c.gate is None))  # a known failure, xfailed
# below (test_fej_without_a_gate_survives_observations_that_fit_no_world)
# one example is a whole run: few of them, and no shrinking (a 10^4-step case shrinks for minutes)
slow = settings(
    max_examples=3,
    deadline=None,
    derandomize=True,  # the same examples on every run: CI must not be a lottery
    database=None,  # nothing written into the checkout
    phases=[Phase.explicit, Phase.reuse, Phase.generate],
    suppress_health_check=[HealthCheck.too_slow],
)


def assert_covariance(ekf: EKFSLAM, step: int) -> None:
    S, mu = ekf.Sigma, ekf.mu
    assert np.isfinite(S).all() and np.isfinite(mu).all(), f"NaN or inf at step {step}"
    assert np.abs(S - S.T).max() <= 1e-12 * max(1.0, np.abs(S).max()), f"asymmetric at {step}"
    smallest = np.linalg.eigvalsh(S)[0]
    assert smallest >= FLOOR * np.trace(S), f"λ_min {smallest:.3e} at step {step}"
    assert -math.pi <= mu[2] < math.pi


@pytest.mark.slow
@slow
@given(
    config=configs,
    seed=st.integers(0, 2**32 - 1),
    n_landmarks=st.integers(1, 12),
    motion_sigma=st.floats(1e-4, 0.2),
    range_sigma=st.floats(1e-3, 0.3),
    bearing_sigma=st.floats(1e-3, 0.3),
    turn=st.floats(0.0, 1.5),
)
def test_sigma_stays_a_covariance_over_10k_steps_of_a_consistent_world(
    config, seed, n_landmarks, motion_sigma, range_sigma, bearing_sigma, turn
):
    """A robot wanders among landmarks; every control and observation is valid and noisy."""
    rng = np.random.default_rng(seed)
    marks = rng.uniform(-4.0, 4.0, (n_landmarks, 2))
    truth = np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi)])
    ekf = EKFSLAM(truth, config=config, record=False)
    M = np.diag([motion_sigma, motion_sigma / 2, motion_sigma * 2]) ** 2
    L = np.sqrt(M)  # diagonal: its own Cholesky factor
    Q = np.diag([range_sigma, bearing_sigma]) ** 2
    for k in range(10_000):
        # head back towards the middle when far out, so landmarks stay in view
        home = wrap_angle(math.atan2(-truth[1], -truth[0]) - truth[2])
        w = 0.5 * home if np.hypot(*truth[:2]) > 5 else turn * rng.standard_normal()
        u = np.array([rng.uniform(0, 0.05), rng.normal(0, 0.01), w * 0.1])
        ekf.predict(u, motion_noise(ekf.mu, M), k * 0.1)
        moved = u + L @ rng.standard_normal(3)
        c, s = math.cos(truth[2]), math.sin(truth[2])
        truth[:2] += (c * moved[0] - s * moved[1], s * moved[0] + c * moved[1])
        truth[2] = wrap_angle(float(truth[2] + moved[2]))
        d = marks - truth[:2]
        r = np.hypot(d[:, 0], d[:, 1])
        b = wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - truth[2])
        for i in np.flatnonzero((r < 3.0) & (r > 0.05) & (np.abs(b) < 1.0))[:3]:
            z = (
                r[i] + range_sigma * rng.standard_normal(),
                wrap_angle(float(b[i] + bearing_sigma * rng.standard_normal())),
            )
            if z[0] > 0:
                ekf.update(int(i), z, Q, k * 0.1)
        if k % 1000 == 999:
            assert_covariance(ekf, k)
    c = ekf.counts
    assert c.predictions == 10_000
    assert ekf.n_landmarks >= 1 and c.accepted + c.rejected >= 10  # the run did observe


@pytest.mark.slow
@slow
@given(config=configs, seed=st.integers(0, 2**32 - 1), n_landmarks=st.integers(1, 6))
def test_sigma_survives_observations_that_fit_no_world(config, seed, n_landmarks):
    """Adversarial but valid data: ranges and bearings drawn at random, big random turns."""
    assume(not (config.linearization == "fej" and config.gate is None))  # see the xfail below
    _adversarial_run(config, seed, n_landmarks)


@pytest.mark.xfail(
    strict=True,
    reason="known: FEJ with the gate off diverges on data that fit no world (Σ -> inf); the "
    "first-estimate Jacobians disagree with the state, ungated innovations throw the pose "
    "far away, and the motion Jacobian of eq. (7) built from predicted positions amplifies it",
)
def test_fej_without_a_gate_survives_observations_that_fit_no_world():
    _adversarial_run(FilterConfig(linearization="fej", gate=None), seed=3, n_landmarks=6)


def _adversarial_run(config: FilterConfig, seed: int, n_landmarks: int) -> None:
    rng = np.random.default_rng(seed)
    ekf = EKFSLAM(rng.normal(0, 1, 3) * (1, 1, 0), np.eye(3) * 0.01, config, record=False)
    Q = np.diag([0.05, 0.05]) ** 2
    for k in range(3000):
        u = rng.normal(0, (0.2, 0.2, 2.0))
        R = np.diag(rng.uniform(1e-6, 1e-2, 3))
        ekf.predict(u, R)
        for _ in range(rng.integers(0, 3)):
            z = (rng.uniform(1e-3, 5.0), rng.uniform(-math.pi, math.pi))
            assert ekf.update(int(rng.integers(n_landmarks)), z, Q) in {
                Outcome.INITIALISED,
                Outcome.ACCEPTED,
                Outcome.REJECTED,
                Outcome.REFUSED,
            }
        if k % 500 == 499:
            assert_covariance(ekf, k)
    assert_covariance(ekf, 3000)


# ----------------------------------------------------------------------------- degenerate geometry
@settings(max_examples=50, deadline=None, database=None)
@given(
    config=configs,
    pose=st.tuples(st.floats(-10, 10), st.floats(-10, 10), st.floats(-3.14, 3.14)),
    r=st.floats(0.0, math.sqrt(MIN_RANGE_SQUARED)),
    bearing=st.floats(-math.pi, math.pi, exclude_max=True),
)
def test_a_zero_range_sighting_is_refused_and_counted(config, pose, r, bearing):
    ekf = EKFSLAM(pose, np.eye(3) * 1e-3, config)
    before = ekf.Sigma.copy()
    assert ekf.update(7, (r, bearing), np.eye(2) * 1e-4) == Outcome.REFUSED
    assert ekf.counts.refused == 1 and ekf.n_landmarks == 0
    np.testing.assert_array_equal(ekf.Sigma, before)
    assert np.isfinite(ekf.mu).all()
    h = ekf.history()
    assert h.outcome_mask(Outcome.REFUSED).sum() == 1  # recorded, not silently dropped


@settings(max_examples=50, deadline=None, database=None)
@given(
    config=configs,
    heading=st.floats(-3.14, 3.14),
    r=st.floats(0.2, 5.0),
    bearing=st.floats(-math.pi, math.pi, exclude_max=True),
)
def test_driving_onto_a_landmark_is_refused_never_nan(config, heading, r, bearing):
    ekf = EKFSLAM((0.5, -0.5, heading), np.eye(3) * 1e-4, config)
    Q = np.eye(2) * 1e-4
    ekf.update(3, (r, bearing), Q)  # the landmark, r ahead at `bearing`
    # drive in the body frame straight onto the landmark's estimate (no noise: R = 0)
    m = ekf.landmark(3)[0]
    d = m - ekf.pose[:2]
    c, s = math.cos(ekf.pose[2]), math.sin(ekf.pose[2])
    ekf.predict((c * d[0] + s * d[1], -s * d[0] + c * d[1], 0.0), np.zeros((3, 3)))
    assert np.hypot(*(ekf.pose[:2] - m)) < 1e-9
    refused = ekf.counts.refused
    for bearing_seen in (0.0, 1.0):
        assert ekf.update(3, (0.3, bearing_seen), Q) == Outcome.REFUSED
    assert ekf.counts.refused == refused + 2
    assert np.isfinite(ekf.mu).all() and np.isfinite(ekf.Sigma).all()
    assert_covariance(ekf, 0)


def test_non_finite_observations_are_an_error_not_a_nan_state():
    ekf = EKFSLAM((0.0, 0.0, 0.0))
    for z in ((math.nan, 0.0), (1.0, math.inf)):
        with pytest.raises(ValueError, match="non-finite"):
            ekf.update(1, z, np.eye(2) * 1e-4)
    assert ekf.n_landmarks == 0 and np.isfinite(ekf.Sigma).all()


@pytest.mark.parametrize("gate", [None, 9.21])
def test_the_invariant_filter_survives_observations_that_fit_no_world(gate):
    # where FEJ without a gate diverges (above): the invariant filter's Jacobians are taken at
    # the latest estimate, so ungated nonsense moves the state without blowing Σ up
    _adversarial_run(FilterConfig(linearization="invariant", gate=gate), seed=3, n_landmarks=6)
