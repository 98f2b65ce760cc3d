"""What `ekfslam.core.filter.ekf.EKFSLAM` is given, checked where it takes it (`ekfslam.checks`).

One function per public entry of the filter, called on the first line of the constructor and of
`predict`, `predict_many` and `update`: a pose of 2 numbers, a 2x2 start covariance, a negative
R, a z with 3 coordinates, a string id or NaN end in one `ConfigError` (ValueError) or
`WrongTypeError` (TypeError) naming the method and the argument, before the state is touched.

A replay checks its run once and then calls the filter with ``validate=False``; a loop of the
user's own calls `predict`, `predict_many` and `update` event after event, so they take a fast
path for small float input (Python floats, C-ordered float arrays) and check a noise matrix (the
same one, call after call) once per distinct content. `check_predict_many` and `check_update`
say (True) when their arrays are float64 and C-ordered already, so the filter hands them to its
steps as they are instead of converting them a second time.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ekfslam import checks
from ekfslam.core.filter.config import FilterConfig
from ekfslam.errors import ConfigError, WrongTypeError
from ekfslam.plausibility import MAX_POSITION, MAX_TIME

#: the last noise matrices found good, by their bytes: a replay passes one M (or R) and one Q
_GOOD_NOISE: dict[tuple[str, int], bytes] = {}
#: the replay-shaped batches `check_predict_many` checks as Python floats
_FAST_SIZE = 64
_ARRAY, _FLOAT = np.ndarray, np.dtype(np.float64)
_REALS = (float, np.float64)  # a Python float, or numpy's (a value read from an array)
_INTS = (int, np.int64)  # a whole-number id: Python's, or one read from an int64 array
_M_KEY = ("EKFSLAM.predict_many: M", 3)
_R_KEY = ("EKFSLAM.predict: R", 3)
_ONE_STEP, _ONE, _NOISE = (1, 3), (1,), (3, 3)  # one step's us, dts and ts, and M


def check_start(pose: Any, pose_covariance: Any, config: Any, record: Any) -> None:
    """`EKFSLAM(pose, pose_covariance, config, record)` (and `FilterState`'s)."""
    checks.pose(pose, "EKFSLAM: pose")
    if pose_covariance is not None:
        checks.covariance(pose_covariance, "EKFSLAM: pose_covariance", 3)
    if config is not None:
        checks.instance(
            config, FilterConfig, "EKFSLAM: config", "build one, e.g. FilterConfig(gate=None)"
        )
    checks.flag(record, "EKFSLAM: record")


def check_predict(u: Any, R: Any, t: Any, control: int = 3, dt: Any = 0.0) -> None:
    """`EKFSLAM.predict(u, R, t, dt=dt)`: u (control,) finite (the motion model's
    `control_size`), R a 3x3 covariance, t a finite time or None, dt a duration >= 0 s."""
    if type(dt) is not float or not 0.0 <= dt <= MAX_TIME:
        checks.real(dt, "EKFSLAM.predict: dt", lo=0.0, hi=MAX_TIME, unit="s")
    if control == 3 and _a_loops_call(u, R, t, _R_KEY):
        return
    what = "an increment (dx, dy, dtheta) in m, m, rad" if control == 3 else "a control"
    checks.array(u, "EKFSLAM.predict: u", (control,), what, bound=MAX_POSITION)
    _noise(R, "EKFSLAM.predict: R", 3)
    if t is not None:
        checks.real(t, "EKFSLAM.predict: t", lo=-MAX_TIME, hi=MAX_TIME, unit="s")


def check_predict_many(us: Any, dts: Any, ts: Any, M: Any, R: Any, control: int = 3) -> bool:
    """`EKFSLAM.predict_many(us, dts, ts, M, R)`: K controls of `control` numbers (the motion
    model's `control_size`; the seed's increments: 3), K durations >= 0, K times, and exactly
    one of M (per second, control x control) and R (per step, 3x3), a covariance. Returns True
    when they are already as the filter's steps take them (float64 C-ordered arrays of those
    shapes: one step and the M found good before), so the filter need not convert them."""
    if control == 3 and _one_plain_step(us, dts, ts, M, R):
        return True
    if (
        control == 3
        and R is None
        and type(M) is _ARRAY
        and M.shape == (3, 3)
        and type(us) is _ARRAY
        and type(dts) is _ARRAY
        and type(ts) is _ARRAY
        and us.dtype is _FLOAT
        and dts.dtype is _FLOAT
        and ts.dtype is _FLOAT
        and us.ndim == 2
        and us.shape[1] == 3
        and dts.ndim == ts.ndim == 1
        and len(us) == len(dts) == len(ts)
        and us.size <= _FAST_SIZE
        and _GOOD_NOISE.get(_M_KEY) == M.tobytes()
    ):  # what the replay passes, event after event: Python floats, no numpy reduction
        u, d, t = us.ravel().tolist(), dts.tolist(), ts.tolist()
        if (
            math.isfinite(sum(u) + sum(d) + sum(t))
            and (not d or (min(d) >= 0.0 and max(d) <= MAX_TIME))
            and (not u or -MAX_POSITION <= min(u) <= max(u) <= MAX_POSITION)
            and (not t or -MAX_TIME <= min(t) <= max(t) <= MAX_TIME)
        ):
            return False
    name = "EKFSLAM.predict_many"
    if (M is None) == (R is None):
        raise ConfigError(f"{name}: give exactly one of M (per second) or R (per step)")
    if M is not None:
        _noise(M, f"{name}: M", control)
    else:
        _noise(R, f"{name}: R", 3)
    k, _ = _rows(us, f"{name}: us", control, bound=MAX_POSITION)
    _rows(ts, f"{name}: ts", None, k, bound=MAX_TIME)
    _, smallest = _rows(
        dts, f"{name}: dts", None, k, bound=MAX_TIME
    )  # R ignores them; K all the same
    if smallest < 0.0:
        raise ConfigError(f"{name}: dts must be durations >= 0 s, got {smallest!r}")
    return False


def _one_plain_step(us: Any, dts: Any, ts: Any, M: Any, R: Any) -> bool:
    """The fast path of `check_predict_many` for a user's loop, one step a call: us (1, 3),
    dts (1,), ts (1,) float64 arrays (us C-ordered; one number is, whatever its strides) and
    the M found good before, C-ordered, read as five Python floats (a NaN fails every
    comparison, so it takes the full check, which names it)."""
    if not (
        R is None
        and type(us) is type(dts) is type(ts) is type(M) is _ARRAY
        and us.dtype is dts.dtype is ts.dtype is M.dtype is _FLOAT
        and us.shape == _ONE_STEP
        and dts.shape == ts.shape == _ONE
        and M.shape == _NOISE
        and M.tobytes() == _GOOD_NOISE.get(_M_KEY)
        and us.flags.c_contiguous
        and M.flags.c_contiguous
    ):
        return False
    ((a, b, c),), (d,), (t,) = us.tolist(), dts.tolist(), ts.tolist()
    p = MAX_POSITION
    return (
        -p <= a <= p
        and -p <= b <= p
        and -p <= c <= p
        and 0.0 <= d <= MAX_TIME
        and -MAX_TIME <= t <= MAX_TIME
    )


def check_update(landmark_id: Any, z: Any, Q: Any, t: Any, size: int = 2) -> bool:
    """`EKFSLAM.update(landmark_id, z, Q, t)`: a whole-number id, z of `size` finite numbers
    (the sensor's `SensorModel.size`; the seed's (r, φ), |r| within the plausible 1e7 m), Q a
    size x size positive-definite covariance, t a plausible time or None. (A negative range is
    the sensor's business, refused by the readers; the filter's algebra takes it.) Returns True
    when z and Q are already as the filter's steps take them (float64 C-ordered arrays), so the
    filter need not convert them."""
    if size == 2 and _a_plain_update(landmark_id, z, Q, t):
        return type(z) is _ARRAY and z.flags.c_contiguous and Q.flags.c_contiguous
    if not checks.is_whole(landmark_id) or not -(2**63) <= int(landmark_id) < 2**63:
        raise WrongTypeError(
            "EKFSLAM.update: landmark_id must be a whole number within 64 bits, got "
            f"{checks.shown(landmark_id)}"
        )
    what = "an observation (range, bearing)" if size == 2 else f"an observation of {size}"
    checks.array(z, "EKFSLAM.update: z", (size,), what, bound=MAX_POSITION)
    _noise(Q, "EKFSLAM.update: Q", size, definite=True)
    if t is not None:
        checks.real(t, "EKFSLAM.update: t", lo=-MAX_TIME, hi=MAX_TIME, unit="s")
    return False


def _a_plain_update(landmark_id: Any, z: Any, Q: Any, t: Any) -> bool:
    """The fast path of `check_update`, for what a loop of the user's calls passes: a Python or
    numpy integer id, z a float64 array of 2 (or a list or tuple of 2 floats) within the bound,
    Q a float64 2x2 array that is surely a positive-definite covariance, t None or a plausible
    float. Read as Python floats, well under a microsecond; False sends the call to the full
    check, which decides (and says what is wrong), so nothing it refuses passes here.

    Q passes when it is exactly symmetric with a > 0, e > 0 and det = ae - b² > 1e-12 (a + e)²:
    then the smaller eigenvalue, det / λ_max >= det / (a + e), exceeds 1e-12 of the larger,
    which is `checks.covariance`'s "definite" (a, e below 1e100, so nothing overflows)."""
    if type(landmark_id) not in _INTS or not -(2**63) <= landmark_id < 2**63:
        return False
    if t is not None and (type(t) not in _REALS or not -MAX_TIME <= t <= MAX_TIME):
        return False
    kind = type(z)
    if kind is _ARRAY:
        if z.dtype is not _FLOAT or z.shape != (2,):
            return False
        r, b = z.tolist()
    elif (kind is list or kind is tuple) and len(z) == 2:
        r, b = z
        if type(r) not in _REALS or type(b) not in _REALS:
            return False
    else:
        return False
    if not (-MAX_POSITION <= r <= MAX_POSITION and -MAX_POSITION <= b <= MAX_POSITION):
        return False
    if type(Q) is not _ARRAY or Q.dtype is not _FLOAT or Q.shape != (2, 2):
        return False
    (a, q01), (q10, e) = Q.tolist()
    return (
        q01 == q10
        and 0.0 < a < 1e100
        and 0.0 < e < 1e100
        and a * e - q01 * q01 > 1e-12 * (a + e) * (a + e)
    )


def check_observe(zs: Any, Q: Any, t: Any, name: str) -> None:
    """An association's `observe(zs, Q, t)`: zs rows of (range, bearing), finite (|r| within
    the plausible 1e7 m), Q a 2x2 positive-definite covariance, t a plausible time; checked
    once for the sightings of one time, which it then feeds the filter unchecked."""
    if (
        type(zs) is list
        and zs
        and type(t) is float
        and -MAX_TIME <= t <= MAX_TIME
        and type(Q) is _ARRAY
        and Q.dtype is _FLOAT
        and Q.shape == (2, 2)
        and _GOOD_NOISE.get((f"{name}: Q", 2)) == Q.tobytes()
        and all(type(z) is list and _plain(z, 2) for z in zs)
    ):  # what a replay passes, time after time: lists of Python floats, the same Q
        return
    checks.array(zs, f"{name}: zs", (None, 2), "sightings (range, bearing)", bound=MAX_POSITION)
    _noise(Q, f"{name}: Q", 2, definite=True)
    checks.real(t, f"{name}: t", lo=-MAX_TIME, hi=MAX_TIME, unit="s")


def _a_loops_call(values: Any, noise: Any, t: Any, key: tuple[str, int]) -> bool:
    """The fast path of `check_predict` and `check_update`: what a loop of the user's calls
    passes, step after step (u or z a list or tuple of n floats within the bound, the noise the
    same n x n float array found good before, t None or a plausible float). False: check in full.
    """
    n = key[1]
    return (
        (type(values) is list or type(values) is tuple)
        and type(noise) is _ARRAY
        and (t is None or (type(t) in _REALS and -MAX_TIME <= t <= MAX_TIME))
        and noise.dtype is _FLOAT
        and noise.shape == (n, n)
        and _GOOD_NOISE.get(key) == noise.tobytes()
        and _plain(values, n)
    )


def _plain(values: list | tuple, n: int) -> bool:
    """Are the values n floats (Python's or numpy's) within the bound the full check puts on a
    z or a u?"""
    if len(values) != n:
        return False
    for x in values:  # a loop, not all(...): a generator costs more than the test
        if type(x) not in _REALS or not -MAX_POSITION <= x <= MAX_POSITION:
            return False
    return True


def _noise(value: Any, name: str, n: int, definite: bool = False) -> None:
    """A noise covariance; an array whose bytes were found good before is not checked again."""
    key = (name, n)
    if type(value) is _ARRAY and value.dtype is _FLOAT and value.shape == (n, n):
        data = value.tobytes()
        if _GOOD_NOISE.get(key) == data:
            return
        checks.covariance(value, name, n, definite=definite)
        _GOOD_NOISE[key] = data
        return
    checks.covariance(value, name, n, definite=definite)


def _rows(
    value: Any, name: str, width: int | None, length: int | None = None, bound: float = math.inf
) -> tuple[int, float]:
    """Check rows of `width` finite numbers ((width,) is one row), or (N,) values when `width`
    is None, `length` of them when given; returns (how many, the smallest value)."""
    shape: tuple[int | None, ...] = (None,) if width is None else (None, width)
    if width is not None and _ndim(value) == 1:
        shape = (width,)
    a = checks.array(value, name, shape, bound=bound)
    count = 1 if a.ndim == 1 and width is not None else len(a)
    if length is not None and count != length:
        raise ConfigError(f"{name}: {length} increments need as many values, got {count}")
    return count, float(a.min()) if a.size else 0.0


def _ndim(value: Any) -> int:
    try:
        return np.ndim(value)
    except (ValueError, TypeError):  # ragged: `checks.array` says so
        return 2
