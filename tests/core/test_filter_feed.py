"""`EKFSLAM.feed` (a run in one call, `steps.feed`) against the filter's own steps one by one.

A replay feeds the filter through `feed`; the loop it stands for is `predict_many` through the
pieces before each detection and `update` with it. Hypothesis draws whole runs whose sightings
take every path: a landmark first seen mid-run, sightings on the robot (refused), outliers the
gate rejects, a landmark placed again after rejections that agree, an innovation covariance
that overflows (singular), noise per detection. The two must agree to the bit (to 1e-12
compiled): μ, Σ, the counts, the sightings each landmark accepted, the time and every column
of the history.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from stepwise import one_by_one

from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.ekf import EKFSLAM, Detections, Pieces
from ekfslam.core.filter.history import Outcome

configs = st.builds(
    FilterConfig,
    init=st.sampled_from(["inverse", "seed"]),
    linearization=st.sampled_from(["standard", "fej", "invariant"]),
    gate=st.sampled_from([None, 9.21, 2.0]),
    gate_after=st.integers(1, 3),
    reinit_after=st.sampled_from([None, 2, 3]),
    reinit_radius=st.sampled_from([0.1, 5.0]),
    initial_capacity=st.integers(1, 3),  # the storage doubles mid-run
)


@st.composite
def runs(draw) -> tuple[Pieces, Detections, np.ndarray]:
    """Pieces and detections in time order, drawn from a seed and a few knobs."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    k, n = draw(st.integers(0, 40)), draw(st.integers(0, 30))
    dt = rng.uniform(0.01, 0.3, k)
    u = rng.normal(0.0, (0.05, 0.02, 0.2), (k, 3)) * dt[:, None] * 10
    t = np.cumsum(dt)
    upto = np.sort(rng.integers(0, k + 1, n)).astype(np.int64)
    ids = rng.integers(0, draw(st.integers(1, 5)), n).astype(np.int64) * 7  # not slot numbers
    z = np.column_stack([rng.uniform(0.3, 2.0, n), rng.uniform(-math.pi, math.pi, n)])
    z[rng.random(n) < draw(st.sampled_from([0.0, 0.1]))] = (0.0, 0.3)  # on the robot
    repeats = rng.random(n) < 0.6  # most sightings agree with the one before of that id
    for i in np.flatnonzero(repeats):
        before = np.flatnonzero(ids[:i] == ids[i])
        if len(before):
            z[i] = z[before[-1]] + rng.normal(0.0, 0.01, 2)
    variance = rng.choice([1e-6, 4e-4, 0.04, 1e300], n, p=[0.3, 0.4, 0.28, 0.02])  # 1e300: S = inf
    Q = variance[:, None, None] * np.eye(2)
    times = np.concatenate([[0.0], t])[upto]
    M = np.diag([0.02, 0.01, 0.05]) ** 2 if draw(st.booleans()) else None
    R = None if M is not None else np.diag([1e-4, 1e-4, 1e-3])
    pose = rng.normal(0.0, 0.2, 3)
    return Pieces(u, dt, t, M, R), Detections(upto, ids, z, np.ascontiguousarray(Q), times), pose


def assert_same(fed: EKFSLAM, stepped: EKFSLAM, record: bool, exact: bool) -> None:
    """The same state, counts and history: to the bit where both run the same Python lines
    (`exact`), to 1e-12 where numba compiled the two paths apart (its code for one CPU may
    round a last digit its own way)."""
    assert fed.counts == stepped.counts
    assert fed.accepted_sightings() == stepped.accepted_sightings()
    assert fed.landmark_ids == stepped.landmark_ids
    assert fed._t == stepped._t
    arrays = [(fed.mu, stepped.mu), (fed.Sigma, stepped.Sigma)]
    if record:
        a, b = fed.history(), stepped.history()
        arrays += [(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a)]
    for x, y in arrays:
        if exact:
            np.testing.assert_array_equal(x, y)
        else:
            np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-12)


def check(config: FilterConfig, run, record: bool) -> EKFSLAM:
    pieces, detections, pose = run
    fed, stepped = (EKFSLAM(pose, np.eye(3) * 1e-3, config, record) for _ in range(2))
    with np.errstate(all="ignore"):
        fed.feed(pieces, detections)
        one_by_one(stepped, pieces, detections)
    assert_same(fed, stepped, record, exact=config.backend == "python")
    return fed


@settings(max_examples=150, deadline=None)
@given(config=configs, run=runs(), record=st.booleans(), iterations=st.sampled_from([1, 3]))
def test_feed_is_the_filters_own_steps_one_by_one(config, run, record, iterations) -> None:
    if config.linearization != "fej":  # (FEJ keeps each Jacobian where it was first evaluated)
        config = dataclasses.replace(config, iterations=iterations)
    check(dataclasses.replace(config, backend="python"), run, record)


@pytest.mark.parametrize("linearization", ["standard", "fej", "invariant"])
@settings(max_examples=15, deadline=None)
@given(config=configs, run=runs())
def test_the_compiled_feed_is_the_compiled_steps_one_by_one(linearization, config, run) -> None:
    config = dataclasses.replace(config, linearization=linearization, backend="numba")
    check(config, run, record=True)


def test_every_path_of_feed_is_taken() -> None:
    # one run whose outcomes include each of them: the drawn runs are not all luck
    rng = np.random.default_rng(5)
    u = np.zeros((60, 3))  # the robot stands: its sightings agree
    dt, t = np.full(60, 0.1), np.arange(1, 61) * 0.1
    upto = np.repeat(np.arange(0, 60, 6), 3).astype(np.int64)
    n = len(upto)
    ids = np.array([1, 2, 3] * (n // 3), dtype=np.int64)
    z = np.tile([[1.0, 0.3], [1.5, -0.4], [0.8, 1.0]], (n // 3, 1)) + rng.normal(0, 1e-3, (n, 2))
    z[9:18:3] += (0.5, 0.0)  # landmark 1 seen elsewhere three times: rejected, then placed again
    ids[4], z[4] = 9, (0.0, 0.2)  # a new landmark on the robot: refused
    Q = np.repeat((np.eye(2) * 1e-4)[None], n, 0)
    Q[7] = np.eye(2) * 1e300  # S overflows: singular
    run = (
        Pieces(u, dt, t, None, np.eye(3) * 1e-6),
        Detections(upto, ids, z, Q, t[upto]),
        np.zeros(3),
    )
    for backend in ("python", "numba"):
        fed = check(FilterConfig(backend=backend), run, record=True)
        assert all(fed.counts.of(o) > 0 for o in Outcome if o != Outcome.DEFERRED), fed.counts
