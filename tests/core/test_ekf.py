"""The efficient filter against the literal reference, and its numerical properties."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ekfslam.core.filter.ekf import CHI2_2DOF_99, EKFSLAM, FilterConfig
from ekfslam.core.filter.history import Outcome
from ekfslam.core.models import motion, observation, observation_noise
from ekfslam.teaching.reference import LiteralEKFSLAM


def random_run(rng: np.random.Generator, steps: int, n_landmarks: int, outlier_rate: float = 0.0):
    """Yield ("predict", u, R) and ("update", id, z, Q) events of a robot wandering among landmarks.

    Landmarks are seen only within 2 m, so they enter the state over time.
    """
    landmarks = rng.uniform(-3, 3, size=(n_landmarks, 2))
    ids = rng.permutation(1000)[:n_landmarks]
    pose = np.array([0.0, 0.0, rng.uniform(-math.pi, math.pi)])
    M = np.diag([0.01, 0.005, 0.01]) ** 2
    Q = observation_noise(0.05, 0.03)
    for _ in range(steps):
        u = np.array([rng.uniform(0.0, 0.1), rng.uniform(-0.03, 0.03), rng.uniform(-0.3, 0.3)])
        if np.hypot(*pose[:2]) > 2.5:  # turn back towards the middle
            u[2] = 0.6
        pose = motion(pose, u + rng.multivariate_normal(np.zeros(3), M))
        R = M  # increments are small: the body-frame noise is close enough for a test run
        yield ("predict", u, R)
        for k in range(n_landmarks):
            z = observation(pose, landmarks[k])
            if z[0] > 2.0 or rng.random() < 0.5:
                continue
            z = z + rng.normal(0, [0.05, 0.03])
            if rng.random() < outlier_rate:
                z[0] += rng.uniform(0.5, 1.5)
            z[1] = (z[1] + math.pi) % (2 * math.pi) - math.pi
            yield ("update", int(ids[k]), z, Q)


def drive(filters, events):
    outcomes = []
    for event in events:
        for f in filters:
            if event[0] == "predict":
                f.predict(event[1], event[2])
            else:
                outcomes.append(f.update(event[1], event[2], event[3]))
    return outcomes


@pytest.mark.parametrize("linearization", ["standard", "fej", "invariant"])
@pytest.mark.parametrize("init", ["inverse", "seed"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_efficient_filter_agrees_with_literal_reference(init, seed, linearization):
    rng = np.random.default_rng(seed)
    # eq. (3)'s "infinite" variance costs digits: after the first update the landmark block is
    # big - big²/(big + σ²), which loses about log10(big/σ²) digits in both implementations, in
    # different places. A moderate stand-in keeps the comparison at 1e-9 meaningful.
    config = FilterConfig(
        init=init, initial_capacity=2, seed_init_variance=1e2, linearization=linearization
    )
    fast = EKFSLAM([0.1, -0.2, 0.3], np.diag([1e-4, 1e-4, 1e-5]), config)
    slow = LiteralEKFSLAM([0.1, -0.2, 0.3], np.diag([1e-4, 1e-4, 1e-5]), config)
    outcomes = []
    for event in random_run(rng, 150, 12, outlier_rate=0.05):
        if event[0] == "predict":
            if rng.random() < 0.3:  # some predictions in batches, as replay does
                us = np.array([event[1] / 2, event[1] / 2])
                fast.predict_many(us, [0.05, 0.05], [0.0, 0.0], R=np.asarray(event[2]))
                slow.predict(us[0], event[2])
                slow.predict(us[1], event[2])
                continue
            fast.predict(event[1], event[2])
            slow.predict(event[1], event[2])
        else:
            a = fast.update(event[1], event[2], event[3])
            b = slow.update(event[1], event[2], event[3])
            assert a == b
            outcomes.append(a)
    assert fast.n_landmarks == slow.n_landmarks >= 5
    assert fast.capacity >= fast.n_landmarks > 2
    np.testing.assert_allclose(fast.mu, slow.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.Sigma, slow.cartesian_Sigma, rtol=0, atol=1e-9)
    # the run exercised every path the oracle checks
    assert outcomes.count(Outcome.ACCEPTED) > 50
    assert outcomes.count(Outcome.REJECTED) > 0
    assert fast.counts == slow.counts


def test_fej_linearizes_elsewhere_than_the_standard_filter():
    """FEJ changes Σ (the Jacobians) but not how ẑ is predicted; the oracle test needs both."""
    events = list(random_run(np.random.default_rng(4), 120, 10))
    standard = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(gate=None))
    fej = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(gate=None, linearization="fej"))
    drive([standard, fej], events)
    assert np.max(np.abs(standard.Sigma - fej.Sigma)) > 1e-6
    assert np.max(np.abs(standard.mu - fej.mu)) > 1e-6
    # with no update between predictions the first estimates are the latest ones: identical
    a = EKFSLAM([0.0, 0.0, 0.3], config=FilterConfig(linearization="fej"))
    b = EKFSLAM([0.0, 0.0, 0.3])
    for f in (a, b):
        f.update(1, [1.0, 0.2], observation_noise(0.05, 0.03))
        for _ in range(5):
            f.predict([0.05, 0.01, 0.1], np.diag([1e-4, 1e-4, 1e-4]))
    np.testing.assert_allclose(a.Sigma, b.Sigma, rtol=0, atol=1e-15)


def test_predict_touches_only_pose_rows_and_columns():
    rng = np.random.default_rng(3)
    f = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(gate=None))
    drive([f], random_run(rng, 60, 8))
    before = f.Sigma.copy()
    f.predict([0.05, 0.01, 0.2], np.diag([1e-4, 1e-4, 1e-4]))
    after = f.Sigma
    np.testing.assert_array_equal(after[3:, 3:], before[3:, 3:])
    assert not np.array_equal(after[:3, 3:], before[:3, 3:])


def test_storage_is_not_copied_per_new_landmark():
    f = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(initial_capacity=4))
    Q = observation_noise(0.05, 0.03)
    buffers = []  # keep them alive: an id() of a freed buffer can be reused
    for k in range(20):
        f.update(k, [1.0 + 0.1 * k, 0.1 * k - 1.0], Q)
        if not any(b is f._storage.Sigma for b in buffers):
            buffers.append(f._storage.Sigma)
    # 4 -> 8 -> 16 -> 32 landmarks: three doublings, not twenty copies
    assert len(buffers) == 4  # the first buffer and three doublings
    assert f.capacity == 32 and f.n_landmarks == 20


@pytest.mark.slow
def test_sigma_symmetric_and_psd_over_ten_thousand_steps():
    rng = np.random.default_rng(7)
    f = EKFSLAM([0.0, 0.0, 0.0], record=False)
    steps = 0
    for event in random_run(rng, 4500, 15, outlier_rate=0.02):
        if event[0] == "predict":
            f.predict(event[1], event[2])
        else:
            f.update(event[1], event[2], event[3])
        steps += 1
    assert steps >= 10_000
    S = f.Sigma
    assert np.max(np.abs(S - S.T)) <= 1e-12
    assert np.linalg.eigvalsh(S).min() >= -1e-9 * np.trace(S)
    assert np.isfinite(f.mu).all()


def test_update_equals_josephs_form():
    rng = np.random.default_rng(11)
    f = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(gate=None))
    drive([f], random_run(rng, 80, 10))
    lid = f.landmark_ids[0]
    j = f.slot[lid]
    mu0, S0 = f.mu.copy(), f.Sigma.copy()
    Q = observation_noise(0.05, 0.03)
    z = observation(mu0[:3], mu0[3 + 2 * j : 5 + 2 * j]) + np.array([0.03, -0.02])
    assert f.update(lid, z, Q) == Outcome.ACCEPTED
    # Joseph's form with a dense H, computed independently
    from ekfslam.core.models import observation_jacobians

    H = np.zeros((2, S0.shape[0]))
    H_p, H_l = observation_jacobians(mu0[:3], mu0[3 + 2 * j : 5 + 2 * j])
    H[:, :3], H[:, 3 + 2 * j : 5 + 2 * j] = H_p, H_l
    K = S0 @ H.T @ np.linalg.inv(H @ S0 @ H.T + Q)
    IKH = np.eye(S0.shape[0]) - K @ H
    joseph = IKH @ S0 @ IKH.T + K @ Q @ K.T
    np.testing.assert_allclose(f.Sigma, joseph, rtol=0, atol=1e-12)


def test_gate_rejects_outliers_and_counts_them():
    f = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(gate_after=1))
    Q = observation_noise(0.02, 0.01)
    assert f.update(5, [1.0, 0.0], Q) == Outcome.INITIALISED
    assert f.update(5, [1.01, 0.005], Q) == Outcome.ACCEPTED
    assert f.update(5, [1.6, 0.0], Q) == Outcome.REJECTED  # 0.6 m off, ~30 sigma
    counts = f.counts
    assert (counts.initialised, counts.accepted, counts.rejected) == (1, 1, 1)
    h = f.history()
    assert [Outcome(k) for k in h.obs_outcome] == [
        Outcome.INITIALISED,
        Outcome.ACCEPTED,
        Outcome.REJECTED,
    ]
    assert h.obs_nis[2] > CHI2_2DOF_99
    # a rejected observation leaves the state alone
    assert h.obs_landmark[2].tolist() == h.obs_landmark[1].tolist()


def test_gate_waits_until_landmark_is_established():
    Q = observation_noise(0.02, 0.01)
    f = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(gate_after=2))
    f.update(5, [1.0, 0.0], Q)
    assert f.update(5, [1.6, 0.0], Q) == Outcome.ACCEPTED  # only one sighting so far: no gate
    g = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(gate=None, gate_after=1))
    g.update(5, [1.0, 0.0], Q)
    assert g.update(5, [1.6, 0.0], Q) == Outcome.ACCEPTED  # gate off


def test_degenerate_geometry_is_refused_and_counted_never_nan():
    Q = observation_noise(0.02, 0.01)
    f = EKFSLAM([0.0, 0.0, 0.0])
    assert f.update(1, [0.0, 0.3], Q) == Outcome.REFUSED  # zero range: no landmark to place
    assert f.n_landmarks == 0
    f.update(2, [0.5, 0.0], Q)
    f.predict([0.5, 0.0, 0.0], np.zeros((3, 3)))  # drive onto the landmark
    assert f.update(2, [0.3, 0.0], Q) == Outcome.REFUSED
    assert f.counts.refused == 2
    assert np.isfinite(f.mu).all() and np.isfinite(f.Sigma).all()
    with pytest.raises(ValueError, match="non-finite"):
        f.update(2, [math.nan, 0.0], Q)


def test_bearing_innovation_is_wrapped_across_pi():
    Q = observation_noise(0.02, 0.02)
    f = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(gate_after=1))
    f.update(3, [1.0, math.pi - 0.01], Q)  # landmark behind the robot
    # the same landmark measured just across the ±π seam: a small innovation, not 2π
    assert f.update(3, [1.0, -math.pi + 0.01], Q) == Outcome.ACCEPTED
    h = f.history()
    assert abs(h.obs_innovation[1, 1]) < 0.03
    assert -math.pi <= f.mu[2] < math.pi


def test_seed_initialisation_approaches_inverse_initialisation():
    """Eq. (3)'s large variance then one update gives (nearly) the inverse-observation init."""
    Q = observation_noise(0.05, 0.03)
    P0 = np.diag([1e-3, 2e-3, 1e-3])
    z = np.array([1.3, 0.7])
    inv = EKFSLAM([0.2, 0.1, 0.4], P0, FilterConfig(init="inverse"))
    inv.update(9, z, Q)
    seed = EKFSLAM([0.2, 0.1, 0.4], P0, FilterConfig(init="seed", seed_init_variance=1e6))
    # regression: the seed's initialisation once counted as an accepted update
    assert seed.update(9, z, Q) == Outcome.INITIALISED
    assert (seed.counts.initialised, seed.counts.accepted) == (1, 0)
    np.testing.assert_allclose(seed.mu, inv.mu, atol=1e-9)
    np.testing.assert_allclose(seed.Sigma, inv.Sigma, rtol=1e-4, atol=1e-8)


def test_history_records_every_event_without_n_squared_copies():
    rng = np.random.default_rng(5)
    f = EKFSLAM([0.0, 0.0, 0.0])
    drive([f], random_run(rng, 50, 6))
    h = f.history()
    c = f.counts
    n_obs = c.initialised + c.accepted + c.rejected + c.refused
    assert len(h.t) == c.predictions + n_obs
    assert h.pose_cov.shape == (len(h.t), 3, 3)
    assert len(h.obs_id) == n_obs
    np.testing.assert_array_equal(h.pose[-1], f.mu[:3])
    accepted = h.outcome_mask(Outcome.ACCEPTED)
    assert np.isfinite(h.obs_nis[accepted]).all()
    assert np.isnan(h.obs_nis[h.outcome_mask(Outcome.INITIALISED)]).all()


@pytest.mark.parametrize("iterations", [1, 3])
@pytest.mark.parametrize("linearization", ["standard", "fej", "invariant"])
def test_the_compiled_steps_compute_what_their_source_says(linearization, iterations):
    """numba's machine code computes what the steps' Python says (which the oracle checks)."""
    if linearization == "fej" and iterations > 1:
        pytest.skip("FEJ does not iterate")

    def run(backend):
        config = FilterConfig(
            linearization=linearization, reinit_after=2, iterations=iterations, backend=backend
        )
        f = EKFSLAM([0.1, -0.2, 0.3], np.diag([1e-4, 1e-4, 1e-5]), config)
        drive([f], random_run(np.random.default_rng(8), 300, 15, outlier_rate=0.1))
        return f

    interpreted, compiled = run("python"), run("numba")
    np.testing.assert_allclose(interpreted.Sigma, compiled.Sigma, rtol=0, atol=1e-12)
    np.testing.assert_allclose(interpreted.mu, compiled.mu, rtol=0, atol=1e-12)
    assert interpreted.counts == compiled.counts
    assert interpreted.counts.accepted > 100 and interpreted.counts.rejected > 5
    a, b = interpreted.history(), compiled.history()
    np.testing.assert_array_equal(a.obs_outcome, b.obs_outcome)
    np.testing.assert_allclose(a.pose_cov, b.pose_cov, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.obs_nis, b.obs_nis, rtol=1e-9, atol=1e-12)


def stepwise_noise(theta: float, M: np.ndarray, dt: float) -> np.ndarray:
    """R = V(θ) (M dt) V(θ)ᵀ built with numpy, independently of the filter's float arithmetic."""
    c, s = math.cos(theta), math.sin(theta)
    V = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return V @ (M * dt) @ V.T


@pytest.mark.parametrize("linearization", ["standard", "fej", "invariant"])
@pytest.mark.parametrize("per_second", [True, False])
def test_predict_many_equals_stepping_predict_one_row_at_a_time(linearization, per_second):
    rng = np.random.default_rng(21)
    config = FilterConfig(gate=None, linearization=linearization)
    Q = observation_noise(0.05, 0.03)
    M = np.array([[4e-4, 1e-5, 2e-5], [1e-5, 1e-4, -1e-5], [2e-5, -1e-5, 9e-4]])
    batched = EKFSLAM([0.3, -0.2, 3.0], np.diag([1e-4, 2e-4, 1e-5]), config)
    stepped = EKFSLAM([0.3, -0.2, 3.0], np.diag([1e-4, 2e-4, 1e-5]), config)
    for k in range(6):  # a map correlated with the pose, so the cross-covariance matters
        for f in (batched, stepped):
            f.update(k, [1.0 + 0.3 * k, -2.5 + 0.9 * k], Q)
    t = 0.0
    for _ in range(8):
        K = int(rng.integers(1, 60))
        us = np.column_stack(
            [rng.uniform(0, 0.05, K), rng.uniform(-0.02, 0.02, K), rng.uniform(-0.4, 0.4, K)]
        )
        dts = rng.uniform(0.01, 0.05, K)
        ts = t + np.cumsum(dts)
        t = ts[-1]
        if per_second:
            batched.predict_many(us, dts, ts, M=M)
            for u, dt, tk in zip(us, dts, ts, strict=True):
                stepped.predict(u, stepwise_noise(stepped.mu[2], M, dt), tk)
        else:
            batched.predict_many(us, dts, ts, R=M)
            for u, tk in zip(us, ts, strict=True):
                stepped.predict(u, M, tk)
        lid = int(rng.integers(0, 6))
        z = observation(batched.mu[:3], batched.landmark(lid)[0]) + rng.normal(0, [0.05, 0.03])
        assert batched.update(lid, z, Q, t) == stepped.update(lid, z, Q, t) == Outcome.ACCEPTED
    np.testing.assert_allclose(batched.mu, stepped.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(batched.Sigma, stepped.Sigma, rtol=0, atol=1e-9)
    a, b = batched.history(), stepped.history()
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_allclose(a.pose, b.pose, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.pose_cov, b.pose_cov, rtol=0, atol=1e-9)
    assert batched.counts == stepped.counts and batched.counts.predictions > 50
    assert np.abs(batched.mu[2]) > 0.1 and np.abs(batched.Sigma[:3, 3:]).max() > 1e-4


@pytest.mark.shared_data
def test_predict_many_equals_stepping_on_a_real_mrclam_log(mrclam7):
    """Robot 1 of MRCLAM Dataset 7, its first 20,000 odometry rows, with its observations."""
    from ekfslam.logs.mrclam.defaults import MRCLAM_NOISE
    from ekfslam.logs.mrclam.load import load_mrclam

    run, _ = load_mrclam(mrclam7, 1)
    rows = 20_000
    t = np.asarray(run.controls.t, dtype=float)[: rows + 1]
    dts = np.diff(t)
    us = run.control_twist()[:rows] * dts[:, None]
    det = run.detections
    keep = (det.t >= t[0]) & (det.t <= t[-1])
    det_t, det_id = det.t[keep], det.tag_id[keep]
    det_z = np.column_stack([det.range, det.bearing])[keep]
    M, Q = MRCLAM_NOISE.motion_density(), MRCLAM_NOISE.Q
    start = run.meta.nominal_start  # where replay starts it
    batched, stepped = EKFSLAM(start), EKFSLAM(start)
    done = 0
    upto = np.searchsorted(t[1:], det_t, side="right")  # rows that end at or before each one
    for i, p in enumerate(upto.tolist()):
        if p > done:
            batched.predict_many(us[done:p], dts[done:p], t[done + 1 : p + 1], M=M)
            for k in range(done, p):
                stepped.predict(us[k], stepwise_noise(stepped.mu[2], M, dts[k]), t[k + 1])
            done = p
        a = batched.update(int(det_id[i]), det_z[i], Q, det_t[i])
        assert stepped.update(int(det_id[i]), det_z[i], Q, det_t[i]) == a
    assert batched.counts.predictions == done > 15_000
    assert batched.counts.accepted > 100 and batched.n_landmarks >= 5
    np.testing.assert_allclose(batched.mu, stepped.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(batched.Sigma, stepped.Sigma, rtol=0, atol=1e-9)
    np.testing.assert_allclose(batched.history().pose_cov, stepped.history().pose_cov, atol=1e-9)


def test_history_keeps_constant_memory_per_event_whatever_the_map_size():
    """No n x n copy per step: the history's bytes per event are the same at n = 4 and n = 300."""
    Q = observation_noise(0.05, 0.03)
    per_event = {}
    for n in (4, 300):
        f = EKFSLAM([0.0, 0.0, 0.0])
        for j in range(n):
            f.update(j, [1.0 + j % 7, -3.0 + 0.02 * j], Q)
        for k in range(200):
            f.predict([0.01, 0.0, 0.01], np.diag([1e-4, 1e-4, 1e-5]))
            f.update(k % n, [1.0 + (k % n) % 7, -3.0 + 0.02 * (k % n)], Q)
        h = f.history()
        arrays = {k: v for k, v in vars(h).items() if isinstance(v, np.ndarray)}
        events = sum(v.nbytes for k, v in arrays.items() if not k.startswith("obs_"))
        observations = sum(v.nbytes for k, v in arrays.items() if k.startswith("obs_"))
        per_event[n] = (events / len(h.t), observations / len(h.obs_t))
    assert per_event[300] == per_event[4]
    # bytes: t, kind, a pose and its 3x3 covariance; one observation's numbers
    assert per_event[300][0] < 110 and per_event[300][1] < 200


def test_large_map_update_agrees_with_literal_reference():
    """Past about 20 landmarks Σ -= WᵀW runs in BLAS, in place, in row blocks: same result."""
    Q = observation_noise(0.05, 0.03)
    rng = np.random.default_rng(12)
    config = FilterConfig(gate=None)
    fast = EKFSLAM([0.0, 0.0, 0.5], np.diag([1e-4, 1e-4, 1e-5]), config)
    slow = LiteralEKFSLAM([0.0, 0.0, 0.5], np.diag([1e-4, 1e-4, 1e-5]), config)
    n = 30
    zs = np.column_stack([rng.uniform(1.0, 4.0, n), rng.uniform(-math.pi, math.pi, n)])
    for k in range(n):
        assert fast.update(k, zs[k], Q) == slow.update(k, zs[k], Q) == Outcome.INITIALISED
    for _ in range(30):
        u, R = [0.02, 0.005, 0.02], np.diag([1e-4, 1e-4, 1e-5])
        fast.predict(u, R)
        slow.predict(u, R)
        j = int(rng.integers(0, n))
        z = observation(fast.mu[:3], fast.landmark(j)[0]) + rng.normal(0, [0.05, 0.03])
        assert fast.update(j, z, Q) == slow.update(j, z, Q) == Outcome.ACCEPTED
    assert fast.Sigma.shape[0] == 3 + 2 * n
    np.testing.assert_allclose(fast.mu, slow.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.Sigma, slow.cartesian_Sigma, rtol=0, atol=1e-9)
    assert np.max(np.abs(fast.Sigma - fast.Sigma.T)) <= 1e-15


@pytest.mark.parametrize("init", ["inverse", "seed"])
def test_a_landmark_initialised_from_an_outlier_is_initialised_again(init):
    """A misread first sighting would otherwise make the gate reject every true one after it."""
    Q = observation_noise(0.02, 0.01)
    config = FilterConfig(init=init, seed_init_variance=1e2)
    fast = EKFSLAM([0.0, 0.0, 0.0], config=config)
    slow = LiteralEKFSLAM([0.0, 0.0, 0.0], config=config)
    truth = np.array([1.0, 0.5])
    outcomes = []
    for k in range(8):
        z = observation(np.zeros(3), truth) + np.array([0.004, -0.002]) * (-1) ** k
        if k == 0:
            z[0] += 0.8  # a gross range error on the very first sighting
        a, b = fast.update(7, z, Q), slow.update(7, z, Q)
        assert a == b
        outcomes.append(a)
        fast.predict([0.0, 0.0, 0.0], np.diag([1e-6, 1e-6, 1e-7]))
        slow.predict([0.0, 0.0, 0.0], np.diag([1e-6, 1e-6, 1e-7]))
    assert outcomes[:4] == [
        Outcome.INITIALISED,
        Outcome.REJECTED,
        Outcome.REJECTED,
        Outcome.REINITIALISED,
    ]
    assert set(outcomes[4:]) == {Outcome.ACCEPTED}
    np.testing.assert_allclose(fast.landmark(7)[0], truth, atol=0.01)
    np.testing.assert_allclose(fast.mu, slow.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.Sigma, slow.cartesian_Sigma, rtol=0, atol=1e-9)
    assert fast.counts.reinitialised == 1
    assert np.linalg.eigvalsh(fast.Sigma).min() > 0


def test_scattered_rejections_do_not_move_a_landmark():
    """Outliers that disagree with each other are not a new place for the landmark."""
    Q = observation_noise(0.02, 0.01)
    f = EKFSLAM([0.0, 0.0, 0.0])
    f.update(7, [1.0, 0.3], Q)
    for extra in (0.5, 1.2, 0.8, 1.6, 0.6):  # gross range errors, each elsewhere
        assert f.update(7, [1.0 + extra, 0.3], Q) == Outcome.REJECTED
    assert f.counts.reinitialised == 0
    assert f.update(7, [1.0, 0.3], Q) == Outcome.ACCEPTED


def test_misread_ids_of_another_landmark_do_not_move_a_landmark():
    """Sightings of tag A reported as tag B agree with each other, but land on A: no re-init."""
    Q = observation_noise(0.02, 0.01)
    f = EKFSLAM([0.0, 0.0, 0.0])
    a, b = np.array([1.0, 0.5]), np.array([1.0, -0.5])
    f.update(1, observation(np.zeros(3), a), Q)
    f.update(2, observation(np.zeros(3), b), Q)
    for _ in range(5):
        assert f.update(2, observation(np.zeros(3), a), Q) == Outcome.REJECTED
    assert f.counts.reinitialised == 0
    np.testing.assert_allclose(f.landmark(2)[0], b, atol=1e-9)


def test_a_well_confirmed_landmark_needs_as_many_agreeing_rejections_to_move():
    """A short run of rejections of a landmark seen many times is drift, not a misplaced landmark.

    On the long loop, the old rule (any `reinit_after` agreeing rejections) re-placed confirmed
    landmarks at loop closure and threw the closure away.
    """
    Q = observation_noise(0.02, 0.01)
    config = FilterConfig()
    fast = EKFSLAM([0.0, 0.0, 0.0], config=config)
    slow = LiteralEKFSLAM([0.0, 0.0, 0.0], config=config)
    truth, moved = np.array([1.0, 0.5]), np.array([1.0, 0.9])
    for k in range(6):  # initialised, then confirmed five times: six accepted sightings
        z = observation(np.zeros(3), truth) + np.array([0.004, -0.002]) * (-1) ** k
        assert fast.update(7, z, Q) == slow.update(7, z, Q) != Outcome.REJECTED
    assert fast._sightings[0] == 6
    outcomes = [fast.update(7, observation(np.zeros(3), moved), Q) for _ in range(6)]
    slow_outcomes = [slow.update(7, observation(np.zeros(3), moved), Q) for _ in range(6)]
    assert outcomes == slow_outcomes == [Outcome.REJECTED] * 5 + [Outcome.REINITIALISED]
    np.testing.assert_allclose(fast.landmark(7)[0], moved, atol=1e-9)
    np.testing.assert_allclose(fast.mu, slow.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.Sigma, slow.cartesian_Sigma, rtol=0, atol=1e-9)


def test_a_singular_or_overflowing_innovation_covariance_is_its_own_outcome() -> None:
    f = EKFSLAM([0.0, 0.0, 0.0])
    assert f.update(1, (1.0, 0.2), 1e-4 * np.eye(2)) == Outcome.INITIALISED
    assert f.update(1, (1.0, 0.2), 1e300 * np.eye(2)) == Outcome.SINGULAR  # det S overflows
    assert f.update(1, (1.0, 0.2), 1e-320 * np.eye(2)) == Outcome.ACCEPTED  # Σ_l still 1e-4
    c = f.counts
    assert (c.singular, c.refused, c.accepted, c.initialised) == (1, 0, 1, 1)
    outcomes = [Outcome(k) for k in f.history().obs_outcome]
    assert outcomes == [Outcome.INITIALISED, Outcome.SINGULAR, Outcome.ACCEPTED]


@pytest.mark.parametrize("noise", ["M", "R"])
def test_predict_many_refuses_durations_and_times_of_another_length(noise) -> None:
    """With R (per step) the durations are not used, but K increments still need K of them:
    the step reads one per increment."""
    ekf = EKFSLAM([0.0, 0.0, 0.0])
    us = np.zeros((3, 3))
    with pytest.raises(ValueError, match="3 increments need as many values"):
        ekf.predict_many(us, [0.1, 0.1], [0.0, 0.1, 0.2], **{noise: 1e-3 * np.eye(3)})
    with pytest.raises(ValueError, match="3 increments need as many values"):
        ekf.predict_many(us, [0.1, 0.1, 0.1], [0.0, 0.1], **{noise: 1e-3 * np.eye(3)})


@pytest.mark.parametrize("linearization", ["standard", "fej", "invariant"])
def test_a_filter_without_history_steps_as_one_with_it(linearization) -> None:
    """record=False skips recording each sighting (`steps.sight`, event -1) and passes a
    loop's arrays on unconverted, strided or not: the state is the recording filter's, to
    the bit."""
    rng = np.random.default_rng(5)
    config = FilterConfig(linearization=linearization, backend="python")
    kept, bare = (EKFSLAM([0.0, 0.0, 0.1], config=config, record=r) for r in (True, False))
    M = np.diag([1e-3, 1e-4, 1e-3])
    Q = np.diag([1e-3, 1e-4])
    for k in range(60):
        u = np.array([[0.05, 0.0, 0.02]]) + rng.normal(0.0, 0.002, (1, 3))
        for f in (kept, bare):
            f.predict_many(u, np.array([0.1]), np.array([0.1 * k]), M=M)
        for i in rng.choice(6, 2, replace=False):
            spaced = np.zeros(4)  # z (range, bearing) at every other entry: a strided view
            spaced[::2] = np.array((2.0 + 0.1 * i, -1.0 + 0.4 * i)) + rng.normal(0.0, 0.01, 2)
            zs = {kept: spaced[::2].copy(), bare: spaced[::2]}
            outcomes = [f.update(int(i), zs[f], Q) for f in (kept, bare)]
            assert outcomes[0] == outcomes[1]
    assert np.array_equal(kept.mu, bare.mu)
    assert np.array_equal(kept.Sigma, bare.Sigma)
    assert kept.counts == bare.counts


def test_a_loops_float_arrays_reach_the_steps_unconverted(monkeypatch) -> None:
    """Once M and Q were found good, a loop's C-ordered float64 arrays pass the fast checks
    and go to the steps as they are: nothing converts them a second time."""
    from ekfslam.core.filter import ekf

    f = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(backend="python"), record=False)
    M, Q = np.diag([1e-3, 1e-4, 1e-3]), np.diag([1e-2, 1e-2])
    step = (np.array([[0.1, 0.0, 0.01]]), np.array([0.1]), np.array([0.1]))
    f.predict_many(*step, M=M)
    f.update(4, np.array([2.0, 0.3]), Q, 0.1)

    def converted(*args):
        raise AssertionError("converted again")

    monkeypatch.setattr(ekf, "_rows", converted)
    monkeypatch.setattr(ekf, "_contiguous", converted)
    f.predict_many(*step, M=M)
    assert f.update(4, np.array([1.95, 0.29]), Q, 0.2) == Outcome.ACCEPTED
    assert f.counts.predictions == 2
