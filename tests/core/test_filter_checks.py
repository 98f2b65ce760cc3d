"""The filter's argument checks (`ekfslam.core.filter_checks`): their fast paths for a loop's
Python floats accept exactly what the full checks accept."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ekfslam.core import filter_checks
from ekfslam.core.filter_checks import (
    _GOOD_NOISE,
    check_observe,
    check_predict,
    check_predict_many,
    check_update,
)
from ekfslam.errors import EkfSlamError

Q = np.diag([0.05**2, 0.03**2])
M = np.diag([1e-3, 1e-3, 1e-2])
numbers = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e7, 1e7 + 1, -1e7 - 1, 1e10, 3e7]),
)


def verdict(check, *args) -> str | None:
    try:
        check(*args)
    except (EkfSlamError, ValueError, TypeError) as exc:
        return type(exc).__name__
    return None


@given(
    r=numbers,
    phi=numbers,
    t=st.one_of(st.none(), numbers),
    as_tuple=st.booleans(),
    as_numpy=st.booleans(),
)
def test_the_updates_fast_path_accepts_what_the_full_check_accepts(
    r, phi, t, as_tuple, as_numpy
) -> None:
    check_update(1, [1.0, 0.1], Q, 0.0)  # Q found good: the fast path's condition
    if as_numpy:  # values read from arrays: numpy's floats
        r, phi, t = np.float64(r), np.float64(phi), None if t is None else np.float64(t)
    z = (r, phi) if as_tuple else [r, phi]
    fast = verdict(check_update, 7, z, Q, t)
    _GOOD_NOISE.clear()  # Q not found good yet: the full check, of the same input
    full = verdict(check_update, 7, z, Q, t)
    assert fast == full


@given(
    u=st.lists(numbers, min_size=2, max_size=4),
    t=st.one_of(st.none(), numbers),
    as_tuple=st.booleans(),
    as_numpy=st.booleans(),
)
def test_the_predictions_fast_path_accepts_what_the_full_check_accepts(
    u, t, as_tuple, as_numpy
) -> None:
    R = np.diag([1e-4, 1e-4, 1e-5])
    check_predict([0.1, 0.0, 0.01], R, 0.0)  # R found good: the fast path's condition
    if as_numpy:  # values read from arrays: numpy's floats
        u, t = [np.float64(x) for x in u], None if t is None else np.float64(t)
    u = tuple(u) if as_tuple else list(u)
    fast = verdict(check_predict, u, R, t)
    _GOOD_NOISE.clear()  # R not found good yet: the full check, of the same input
    full = verdict(check_predict, u, R, t)
    assert fast == full


@given(
    zs=st.lists(st.tuples(numbers, numbers), min_size=0, max_size=4),
    t=numbers,
)
def test_an_observes_fast_path_accepts_what_the_full_check_accepts(zs, t) -> None:
    name = "AssociatingFilter.observe"
    check_observe([[1.0, 0.1]], Q, 0.0, name)  # Q found good: the fast path's condition
    zs = [list(z) for z in zs]
    fast = verdict(check_observe, zs, Q, t, name)
    _GOOD_NOISE.clear()  # Q not found good yet: the full check, of the same input
    full = verdict(check_observe, zs, Q, t, name)
    assert fast == full


@given(
    us=st.lists(st.tuples(numbers, numbers, numbers), min_size=0, max_size=5),
    dt=numbers,
    t=numbers,
)
def test_the_batch_fast_path_accepts_what_the_full_check_accepts(us, dt, t) -> None:
    check_predict_many(np.zeros((1, 3)), np.ones(1), np.zeros(1), M, None)  # M found good
    u = np.array(us, dtype=float).reshape(-1, 3)
    dts, ts = np.full(len(u), dt), np.full(len(u), t)
    fast = verdict(check_predict_many, u, dts, ts, M, None)
    _GOOD_NOISE.clear()  # M not found good yet: the full check
    full = verdict(check_predict_many, u.copy(), dts.copy(), ts.copy(), M.copy(), None)
    assert fast == full


@pytest.mark.parametrize("z", [(1.0, 0.2), [1.0, 0.2], (np.float64(1.0), np.float64(0.2))])
@pytest.mark.parametrize("t", [None, 3.0])
def test_a_loops_floats_take_the_fast_path(z, t, monkeypatch) -> None:
    check_update(1, [1.0, 0.1], Q, 0.0)

    monkeypatch.setattr(
        filter_checks.checks, "array", lambda *a, **k: pytest.fail("the full check ran")
    )
    check_update(2, z, Q, t)


@pytest.mark.parametrize("u", [(0.1, 0.0, 0.01), [0.1, 0.0, 0.01], tuple(np.array([0.1, 0, 0.01]))])
@pytest.mark.parametrize("t", [None, 3.0])
def test_a_loops_increments_take_the_fast_path(u, t, monkeypatch) -> None:
    R = np.diag([1e-4, 1e-4, 1e-5])
    check_predict([0.0, 0.0, 0.0], R, 0.0)

    monkeypatch.setattr(
        filter_checks.checks, "array", lambda *a, **k: pytest.fail("the full check ran")
    )
    check_predict(u, R, t)


@settings(max_examples=300, deadline=None)
@given(
    q=st.lists(
        st.one_of(
            st.floats(-1e3, 1e3),
            st.floats(1e-300, 1e-200),
            st.sampled_from([0.0, 1e-12, math.nan, math.inf, -math.inf, 1e150]),
        ),
        min_size=4,
        max_size=4,
    ),
    z=st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=2, max_size=2),
)
def test_the_fast_path_of_update_passes_only_what_the_full_check_passes(q, z) -> None:
    """`check_update`'s fast path (Python floats, well under a microsecond) never lets through
    what the full check (`checks.covariance`, numpy's eigenvalues) refuses (an int32 id takes
    the full path)."""
    Q, zs = np.array(q, dtype=float).reshape(2, 2), np.array(z, dtype=float)
    if filter_checks._a_plain_update(3, zs, Q, 1.0):
        filter_checks._GOOD_NOISE.clear()  # the full check itself, not its cache
        filter_checks.check_update(np.int32(3), list(map(float, zs)), Q.tolist(), 1.0)


def test_the_checks_say_when_the_arguments_are_as_the_steps_take_them() -> None:
    """True only for float64 C-ordered arrays (the filter then passes them on unconverted);
    a list, a strided view or a transposed noise is taken, and converted by the filter."""
    check_update(1, [1.0, 0.1], Q, 0.0)
    assert check_update(1, np.array([1.0, 0.1]), Q, 0.0) is True
    assert check_update(1, [1.0, 0.1], Q, 0.0) is False
    assert check_update(1, np.array([1.0, 9.0, 0.1])[::2], Q, 0.0) is False
    assert check_update(1, np.array([1.0, 0.1]), np.asfortranarray(Q + 1e-4), 0.0) is False
    us, dts, ts = np.array([[0.1, 0.0, 0.01]]), np.ones(1), np.zeros(1)
    check_predict_many(us, dts, ts, M, None)
    assert check_predict_many(us, dts, ts, M, None) is True
    assert check_predict_many(np.zeros((1, 6))[:, ::2], dts, ts, M, None) is False
    assert check_predict_many(us, dts, ts, np.asfortranarray(M + np.eye(3)), None) is False
    assert check_predict_many(np.zeros((2, 3)), np.ones(2), np.zeros(2), M, None) is False
    assert check_predict_many(us.tolist(), [1.0], [0.0], M, None) is False
