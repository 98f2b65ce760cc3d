"""ekfslam.checks and ekfslam.fieldtypes: the validation layer every public function calls first.

The messages are what a student reads, so they are asserted whole where they are short; the
error types are asserted so that ``except ValueError`` keeps catching every bad argument.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ekfslam import checks
from ekfslam.errors import (
    AlignmentError,
    ConfigError,
    EkfSlamError,
    InputError,
    OutputError,
    WrongTypeError,
)
from ekfslam.fieldtypes import field_types


def test_the_hierarchy_keeps_except_valueerror_working() -> None:
    assert issubclass(WrongTypeError, TypeError) and issubclass(WrongTypeError, ValueError)
    for kind in (ConfigError, InputError, AlignmentError):
        assert issubclass(kind, ValueError) and issubclass(kind, EkfSlamError)
    assert issubclass(OutputError, OSError)
    assert len(str(ConfigError("x" * 5000))) == 600
    assert str(InputError("a.csv", 3, "two\nlines")) == "a.csv:3: two lines"


@pytest.mark.parametrize(
    ("call", "kind", "message"),
    [
        (
            lambda: checks.real("0.1", "NoiseConfig.sigma_x"),
            WrongTypeError,
            "NoiseConfig.sigma_x must be a number, got '0.1' (str)",
        ),
        (lambda: checks.real(True, "s"), WrongTypeError, "s must be a number, got True (bool)"),
        (lambda: checks.real(math.nan, "s"), ConfigError, "s must be a finite number, got nan"),
        (lambda: checks.real(-1, "s", lo=0), ConfigError, "s must be >= 0, got -1.0"),
        (
            lambda: checks.whole(2.0, "n"),
            WrongTypeError,
            "n must be a whole number, got 2.0 (float)",
        ),
        (
            lambda: checks.whole(0, "n", lo=1, hi=3),
            ConfigError,
            "n must be a whole number from 1 to 3, got 0",
        ),
        (lambda: checks.flag("no", "f"), WrongTypeError, "f must be True or False, got 'no' (str)"),
        (
            lambda: checks.choice("icp", "align: method", ("mean_distance",)),
            ConfigError,
            "align: method must be one of 'mean_distance', got 'icp' (str)",
        ),
        (
            lambda: checks.choice(np.zeros(0), "m", ("a",)),
            WrongTypeError,
            "m must be one of 'a', got an array of shape (0,) (float64)",
        ),
        (
            lambda: checks.path("", "read_run: folder"),
            ConfigError,
            "read_run: folder is an empty path ''; name a file or folder",
        ),
        (
            lambda: checks.path(None, "f"),
            WrongTypeError,
            "f must be a path (str or pathlib.Path), got None",
        ),
        (
            lambda: checks.path(b"/x", "f"),
            WrongTypeError,
            "f must be a path as text (str or pathlib.Path), got bytes",
        ),
        (
            lambda: checks.pose([0, 0], "p"),
            ConfigError,
            "p must be a pose (x, y, theta) in m, m, rad: 3 numbers, got 2",
        ),
        (
            lambda: checks.point([0, 0, 0], "q"),
            ConfigError,
            "q must be a point (x, y) in m: 2 numbers, got 3",
        ),
        (
            lambda: checks.vector([1, math.inf], "z", 2),
            ConfigError,
            "z must be finite numbers, got a non-finite inf at index 1",
        ),
        (
            lambda: checks.vector(["1", "2"], "z", 2),
            WrongTypeError,
            "z must be 2 numbers, got ['1', '2'] (list)",
        ),
        (
            lambda: checks.array([[1, 2], [3]], "a", (None, 2)),
            ConfigError,
            "a must be an array of shape (N, 2), got a ragged list [[1, 2], [3]] (list)",
        ),
        (
            lambda: checks.covariance(np.eye(2), "S0", 3),
            ConfigError,
            "S0 must be a 3x3 covariance matrix of shape (3, 3), got shape (2, 2)",
        ),
        (
            lambda: checks.covariance([[1, 1], [0, 1]], "S", 2),
            ConfigError,
            "S must be symmetric (a 2x2 covariance matrix); it differs from its transpose by 1",
        ),
        (
            lambda: checks.covariance(-np.eye(3), "S", 3),
            ConfigError,
            "S must be positive semi-definite (a 3x3 covariance matrix: variances >= 0); its "
            "smallest eigenvalue is -1 (a sign error?)",
        ),
        (
            lambda: checks.covariance(np.zeros((2, 2)), "Q", 2, definite=True),
            ConfigError,
            "Q must be positive definite (a 2x2 covariance matrix, every variance > 0); its "
            "smallest eigenvalue is 0",
        ),
        (
            lambda: checks.points_by_id([(0, 0)], "align: truth"),
            WrongTypeError,
            "align: truth must be a mapping {landmark id: (x, y)}, got [(0, 0)] (list)",
        ),
        (
            lambda: checks.points_by_id({"a": (0, 0)}, "m"),
            ConfigError,
            "m: landmark ids must be integers, got 'a' (str)",
        ),
        (
            lambda: checks.instance("runs/x", Path, "replay: run", "read it first"),
            WrongTypeError,
            "replay: run must be a Path, got 'runs/x' (str): read it first",
        ),
    ],
)
def test_each_validator_names_the_argument_and_what_is_wrong(call, kind, message) -> None:
    with pytest.raises(kind) as caught:
        call()
    assert str(caught.value) == message


def test_validators_return_what_they_checked() -> None:
    assert checks.real(np.float32(0.5), "s") == 0.5 and type(checks.real(1, "s")) is float
    assert checks.whole(np.int64(3), "n") == 3
    assert checks.path("~/x", "p") == Path.home() / "x"
    np.testing.assert_array_equal(checks.rows([1, 2, 3, 4], "w", 4), [1.0, 2.0, 3.0, 4.0])
    assert checks.rows([[1, 2, 3, 4]] * 2, "w", 4).shape == (2, 4)
    assert checks.covariance(np.zeros((3, 3)), "S0", 3).shape == (3, 3)  # a known start
    assert checks.points_by_id({np.int64(1): (0, 1)}, "m")[1].tolist() == [0.0, 1.0]


@dataclass(frozen=True)
class _Config:
    gate: float | None = 9.21
    count: int = 3
    name: Literal["a", "b"] = "a"
    start: tuple[float, float, float] | None = None
    flag: bool = True

    def __post_init__(self) -> None:
        field_types(self)


@pytest.mark.parametrize(
    ("kwargs", "kind", "message"),
    [
        ({"gate": "9"}, WrongTypeError, "_Config.gate must be a number or None, got '9' (str)"),
        ({"count": 2.0}, WrongTypeError, "_Config.count must be a whole number, got 2.0 (float)"),
        ({"count": True}, WrongTypeError, "_Config.count must be a whole number, got True (bool)"),
        ({"name": "c"}, ConfigError, "_Config.name must be one of 'a', 'b', got 'c' (str)"),
        ({"start": (0, 0)}, ConfigError, "_Config.start must be 3 numbers, got 2: (0, 0) (tuple)"),
        (
            {"start": "0 0 0"},
            WrongTypeError,
            "_Config.start must be a tuple of 3 numbers or None, got '0 0 0' (str)",
        ),
        ({"flag": "yes"}, WrongTypeError, "_Config.flag must be True or False, got 'yes' (str)"),
    ],
)
def test_field_types_checks_a_dataclass_against_its_annotations(kwargs, kind, message) -> None:
    with pytest.raises(kind) as caught:
        _Config(**kwargs)
    assert str(caught.value) == message


def test_field_types_takes_what_the_annotations_allow() -> None:
    c = _Config(gate=np.float64(5.0), count=np.int64(2), start=[0, 0, np.float32(1)])
    assert c.count == 2 and _Config(gate=None).gate is None


@given(
    values=hnp.arrays(
        np.float64,
        hnp.array_shapes(min_dims=1, max_dims=2, min_side=1, max_side=9),
        elements=st.floats(allow_nan=True, allow_infinity=True, width=64),
    ),
    bound=st.one_of(st.none(), st.floats(0.0, 1e300)),
)
def test_a_small_float_array_is_refused_exactly_when_a_value_is_bad(values, bound) -> None:
    """`checks.array` takes up to 64 float64 values as Python floats (a user's loop checks a z
    per call); it must refuse what numpy's check refuses, and name the first bad entry, for any
    values: NaN, inf, beyond the bound, or finite ones whose sum overflows."""
    beyond = np.abs(values) > (math.inf if bound is None else bound)
    bad = ~np.isfinite(values) if not np.isfinite(values).all() else beyond  # what is said first
    if bad.any():
        with pytest.raises(ConfigError) as raised:
            checks.array(values, "f: a", (None,) * values.ndim, bound=bound)
        first = tuple(int(i) for i in np.argwhere(bad)[0])
        where = first[0] if len(first) == 1 else first
        assert f"at index {where}" in str(raised.value)
    else:
        out = checks.array(values, "f: a", (None,) * values.ndim, bound=bound)
        assert out is values or np.array_equal(out, values)
