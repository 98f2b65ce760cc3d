"""Generated bad arguments for every public function a notebook user calls (issue 27).

For each function exported by `ekfslam` (and the filter's methods), a valid call is written down
once (`SPECS`); hypothesis then replaces one argument by anything a student might pass instead
(None, a string, a path, a dict, a number of the wrong kind, another ekfslam object, an array of
another shape, NaN, inf, 1e300 at any place) and asserts the one property: the call ends in one
of our errors, a ValueError or TypeError whose one-line message names the function or the
argument, within `generated.CASE_SECONDS`; or it returns a result that is finite. Passing an
argument in another form (a list for an array, a numpy scalar for a float) gives the very same
result. The number of cases per function is the hypothesis profile's; tests/conftest.py prints
how many each function saw.
"""

from __future__ import annotations

import dataclasses
import math
import os
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from generated import seen, verdict
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import ekfslam
from ekfslam.core.association import AssociationConfig
from ekfslam.logs.edit import truncate
from ekfslam.sim.team import simulate_team

REPO = Path(__file__).resolve().parents[1]
SEED_RUN = REPO / "data" / "runs" / "square-2laps"
FILES = ("controls.csv", "detections.csv", "groundtruth.csv", "run.json")


@dataclass
class Spec:
    """A function and a valid call of it: each argument's name and a factory of a valid value.

    call(**kwargs) calls it; `arrays` names the arguments that are arrays (perturbed element by
    element, or in shape); `result` turns what it returned into numbers that must be finite.
    """

    name: str
    call: Callable[..., Any]
    args: dict[str, Callable[[], Any]]
    arrays: tuple[str, ...] = ()
    result: Callable[[Any], Any] = lambda value: ()
    forms: tuple[str, ...] = field(default=())  # arguments that may come as list/tuple


class _Inputs:
    """The valid objects the calls are built from, made once."""

    def __init__(self) -> None:
        self.run = truncate(ekfslam.simulate(ekfslam.SimulationConfig(laps=1, seed=2)), 8.0)
        self.result = ekfslam.replay(self.run)
        self.geometry = ekfslam.MecanumGeometry()
        team = simulate_team((0.5, 1.0), ekfslam.SimulationConfig(laps=1, seed=2))
        s, end = team.sightings, 8.0  # the team's first 8 s: its runs and robot sightings
        kept = s.t <= end
        self.team = dataclasses.replace(
            team,
            runs={k: truncate(run, end) for k, run in team.runs.items()},
            sightings=type(s)(**{f.name: getattr(s, f.name)[kept] for f in dataclasses.fields(s)}),
        )


INPUTS: list[_Inputs] = []
_ROOT = tempfile.TemporaryDirectory(prefix="ekfslam-api-")  # removed when the process ends


@pytest.fixture(autouse=True, scope="module")
def _in_a_scratch_folder():
    """Generated paths are often relative ("1.5", "false"): written where the test runs, they
    would litter the checkout. The module runs inside its own temporary folder."""
    here = Path.cwd()
    os.chdir(_ROOT.name)
    yield
    os.chdir(here)


def _in() -> _Inputs:
    if not INPUTS:
        INPUTS.append(_Inputs())
    return INPUTS[0]


def _out() -> Path:
    return Path(tempfile.mkdtemp(dir=_ROOT.name)) / "out"


def _filter() -> ekfslam.EKFSLAM:
    f = ekfslam.EKFSLAM([0.0, 0.0, 0.0])
    f.update(1, [1.0, 0.2], np.diag([1e-3, 1e-3]))
    return f


def _finite(*arrays: Any) -> tuple:
    return tuple(np.asarray(a, dtype=float) for a in arrays)


TWO_MAPS = (
    {0: (0.0, 0.0), 1: (1.0, 0.0), 2: (0.0, 1.0)},
    {0: (0.1, 0.0), 1: (1.1, 0.1), 2: (0.0, 1.1)},
)

SPECS = [
    Spec("read_run", ekfslam.read_run, {"folder": lambda: SEED_RUN, "detections": lambda: None}),
    Spec(
        "write_run",
        ekfslam.write_run,
        {
            "run": lambda: _in().run,
            "folder": _out,
            "overwrite": lambda: False,
            "with_detections": lambda: True,
            "decimals": lambda: None,
        },
    ),
    Spec(
        "replay",
        ekfslam.replay,
        {
            "run": lambda: _in().run,
            "noise": lambda: ekfslam.NoiseConfig(),
            "config": lambda: ekfslam.FilterConfig(),
            "start": lambda: np.array(_in().run.meta.nominal_start),
            "association": lambda: AssociationConfig(method="known"),
            "keyframes": lambda: None,
        },
        arrays=("start",),
        result=lambda r: _finite(r.mu, r.Sigma),
        forms=("start",),
    ),
    Spec(
        "replay_team",
        ekfslam.replay_team,
        {
            "team": lambda: _in().team,
            "noise": lambda: ekfslam.NoiseConfig(),
            "config": lambda: ekfslam.FilterConfig(),
            "anchor": lambda: 1,
            "known_starts": lambda: True,
            "robot_noise_scale": lambda: 0.5,
            "backend": lambda: "python",
        },
        result=lambda r: _finite(*(r.tracks[k].pose for k in r.robots)),
    ),
    Spec(
        "Start.replay",
        lambda pose, covariance: ekfslam.replay(_in().run, start=ekfslam.Start(pose, covariance)),
        {
            "pose": lambda: np.array(_in().run.meta.nominal_start),
            "covariance": lambda: 1e-4 * np.eye(3),
        },
        arrays=("pose", "covariance"),
        result=lambda r: _finite(r.mu, r.Sigma),
        forms=("pose", "covariance"),
    ),
    Spec(
        "HiddenIds",
        ekfslam.HiddenIds,
        {
            "association": lambda: AssociationConfig(method="jcbb"),
            "passes": lambda: 2,
            "map_noise": lambda: None,
        },
    ),
    Spec("KnownIds", ekfslam.KnownIds, {"recovery": lambda: None}),
    Spec(
        "simulate",
        ekfslam.simulate,
        {
            "config": lambda: ekfslam.SimulationConfig(laps=1, size=0.5),
            "arena": lambda: ekfslam.SEED_ARENA,
        },
        result=lambda run: _finite(run.controls.values, run.groundtruth.pose),
    ),
    Spec(
        "summarize",
        ekfslam.summarize,
        {
            "run": lambda: _in().run,
            "result": lambda: _in().result,
            "method": lambda: "mean_distance",
        },
    ),
    Spec(
        "align",
        ekfslam.align,
        {
            "estimated": lambda: dict(TWO_MAPS[0]),
            "truth": lambda: dict(TWO_MAPS[1]),
            "method": lambda: "mean_distance",
        },
        result=lambda a: _finite(a.transform, a.errors),
    ),
    Spec(
        "align_least_squares",
        ekfslam.align_least_squares,
        {
            "estimated": lambda: np.array(list(TWO_MAPS[0].values())),
            "truth": lambda: np.array(list(TWO_MAPS[1].values())),
        },
        arrays=("estimated", "truth"),
        result=lambda a: _finite(a.transform, a.errors),
        forms=("estimated", "truth"),
    ),
    Spec(
        "align_mean_distance",
        ekfslam.align_mean_distance,
        {
            "estimated": lambda: np.array(list(TWO_MAPS[0].values())),
            "truth": lambda: np.array(list(TWO_MAPS[1].values())),
            "tol": lambda: 1e-12,
            "max_iterations": lambda: 1000,
        },
        arrays=("estimated", "truth"),
        result=lambda a: _finite(a.transform, a.errors),
        forms=("estimated", "truth"),
    ),
    Spec(
        "Alignment.apply",
        lambda points: _alignment().apply(points),
        {"points": lambda: np.array([[0.0, 1.0], [2.0, 3.0]])},
        arrays=("points",),
        result=lambda v: _finite(v),
        forms=("points",),
    ),
    Spec(
        "Alignment.start_pose",
        lambda nominal_start: _alignment().start_pose(nominal_start),
        {"nominal_start": lambda: np.array([-0.375, -0.375, 0.0])},
        arrays=("nominal_start",),
        result=lambda v: _finite(v),
        forms=("nominal_start",),
    ),
    Spec(
        "ate_rmse",
        ekfslam.ate_rmse,
        {"result": lambda: _in().result, "groundtruth": lambda: _in().run.groundtruth},
        result=lambda x: _finite(x),
    ),
    Spec(
        "wheels_to_twist",
        ekfslam.wheels_to_twist,
        {
            "wheels": lambda: np.array([[1.0, 2.0, 3.0, 4.0], [0.5, 0.5, 0.5, 0.5]]),
            "geometry": lambda: _in().geometry,
        },
        arrays=("wheels",),
        result=lambda v: _finite(v),
        forms=("wheels",),
    ),
    Spec(
        "twist_to_wheels",
        ekfslam.twist_to_wheels,
        {"twist": lambda: np.array([0.1, 0.0, 0.3]), "geometry": lambda: _in().geometry},
        arrays=("twist",),
        result=lambda v: _finite(v),
        forms=("twist",),
    ),
    Spec("default_noise", ekfslam.default_noise, {"run": lambda: _in().run}),
    Spec(
        "NoiseConfig",
        ekfslam.NoiseConfig,
        {n: (lambda v=v: v) for n, v in dataclasses.asdict(ekfslam.NoiseConfig()).items()},
    ),
    Spec(
        "FilterConfig",
        ekfslam.FilterConfig,
        {n: (lambda v=v: v) for n, v in dataclasses.asdict(ekfslam.FilterConfig()).items()},
    ),
    Spec(
        "SimulationConfig",
        ekfslam.SimulationConfig,
        {
            n: (lambda n=n: getattr(ekfslam.SimulationConfig(), n))
            for n in (
                *("trajectory", "size", "laps", "seed", "controls_hz", "camera_hz", "max_speed"),
                *("start_error", "camera_mounting", "dropout", "wheel_noise_sigma", "robot"),
                "camera",
            )
        },
    ),
    Spec(
        "MecanumGeometry",
        ekfslam.MecanumGeometry,
        {"wheel_radius": lambda: 0.03, "lx": lambda: 0.068, "ly": lambda: 0.054},
    ),
    Spec(
        "Arena",
        ekfslam.Arena,
        {
            "half_size": lambda: 0.75,
            "tags": lambda: ekfslam.SEED_ARENA.tags,
            "nominal_start": lambda: np.array([-0.375, -0.375, 0.0]),
        },
        arrays=("nominal_start",),
    ),
    Spec(
        "EKFSLAM",
        ekfslam.EKFSLAM,
        {
            "pose": lambda: np.array([0.1, -0.2, 0.3]),
            "pose_covariance": lambda: 1e-4 * np.eye(3),
            "config": lambda: ekfslam.FilterConfig(),
            "record": lambda: True,
        },
        arrays=("pose", "pose_covariance"),
        result=lambda f: _finite(f.mu, f.Sigma),
        forms=("pose", "pose_covariance"),
    ),
    Spec(
        "EKFSLAM.predict",
        lambda **kw: _filter_predict(**kw),
        {
            "u": lambda: np.array([0.1, 0.0, 0.05]),
            "R": lambda: 1e-4 * np.eye(3),
            "t": lambda: 0.5,
            "dt": lambda: 0.1,
        },
        arrays=("u", "R"),
        result=lambda f: _finite(f.mu, f.Sigma),
        forms=("u", "R"),
    ),
    Spec(
        "EKFSLAM.predict_many",
        lambda **kw: _filter_predict_many(**kw),
        {
            "us": lambda: np.array([[0.1, 0.0, 0.05], [0.1, 0.0, 0.0]]),
            "dts": lambda: np.array([0.1, 0.1]),
            "ts": lambda: np.array([0.1, 0.2]),
            "M": lambda: 1e-4 * np.eye(3),
        },
        arrays=("us", "dts", "ts", "M"),
        result=lambda f: _finite(f.mu, f.Sigma),
        forms=("us", "dts", "ts", "M"),
    ),
    Spec(
        "EKFSLAM.update",
        lambda **kw: _filter_update(**kw),
        {
            "landmark_id": lambda: 1,
            "z": lambda: np.array([1.05, 0.21]),
            "Q": lambda: np.diag([1e-3, 1e-3]),
            "t": lambda: 0.3,
        },
        arrays=("z", "Q"),
        result=lambda f: _finite(f.mu, f.Sigma),
        forms=("z", "Q"),
    ),
]


def _alignment() -> ekfslam.Alignment:
    return ekfslam.align(*TWO_MAPS)


def _filter_predict(**kw: Any) -> ekfslam.EKFSLAM:
    f = _filter()
    f.predict(**kw)
    return f


def _filter_predict_many(**kw: Any) -> ekfslam.EKFSLAM:
    f = _filter()
    f.predict_many(**kw)
    return f


def _filter_update(**kw: Any) -> ekfslam.EKFSLAM:
    f = _filter()
    f.update(**kw)
    return f


# ------------------------------------------------------------------------------ what is passed
SPECIALS = [
    None,
    True,
    0,
    -1,
    10**20,
    math.nan,
    math.inf,
    -math.inf,
    1e300,
    -0.0,
    np.float32(1.5),
    np.int64(3),
    "",
    "1.5",
    "square",
    b"data",
    Path("data/runs/square-2laps"),
    str(SEED_RUN),
    [],
    [1.0],
    [1.0, 2.0],
    [[1.0, 2.0], [3.0]],
    (1.0, 2.0, 3.0, 4.0),
    {},
    {"sigma_x": 0.1},
    {0: (0.0, 0.0), 1: (1.0, 0.0)},
    object(),
    np.zeros(0),
    np.eye(2),
    -np.eye(3),
    np.full(3, math.nan),
    np.array(["1", "2", "3"]),
]


def _objects() -> list[Any]:
    """Other ekfslam objects, each a wrong argument somewhere."""
    i = _in()
    return [
        i.run,
        i.result,
        i.geometry,
        i.run.controls,
        i.run.groundtruth,
        ekfslam.NoiseConfig(),
        ekfslam.FilterConfig(),
        ekfslam.SEED_ARENA,
        ekfslam.SimulationConfig(),
    ]


anything = st.one_of(
    st.sampled_from(SPECIALS),
    st.integers(0, 8).map(lambda k: _objects()[k]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=6),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
    hnp.arrays(
        np.float64,
        hnp.array_shapes(min_dims=0, max_dims=3, max_side=4),
        elements=st.floats(allow_nan=True, allow_infinity=True),
    ),
)


@st.composite
def perturbed(draw, valid: Any) -> Any:
    """`valid` (an array) with one element NaN, inf or huge, or its shape changed."""
    a = np.array(valid, dtype=float)
    how = draw(st.sampled_from(["element", "drop", "add", "nest", "flat", "transpose"]))
    if how == "element" and a.size:
        i = draw(st.integers(0, a.size - 1))
        bad = [math.nan, math.inf, -math.inf, 1e300, -1e300, 1e15]
        a.reshape(-1)[i] = draw(st.sampled_from(bad))
        return a
    if how == "drop" and a.size:
        return a.reshape(-1)[:-1]
    if how == "add":
        return np.append(a.reshape(-1), 1.0)
    if how == "nest":
        return a[None]
    if how == "transpose" and a.ndim == 2:
        return np.ascontiguousarray(a.T[:, :1])
    return a.reshape(-1)


def _names(spec: Spec, argument: str) -> tuple[str, ...]:
    short = spec.name.split(".")[-1]
    return (spec.name, short, argument, *FILES)


def _call(spec: Spec, kwargs: dict[str, Any]) -> None:
    seen(spec.name)
    kind, value = verdict(lambda: spec.call(**kwargs), _names(spec, ""))
    if kind == "ok":
        for a in spec.result(value):
            assert np.isfinite(a).all(), f"{spec.name} returned non-finite numbers: {a}"


@pytest.mark.parametrize("spec", SPECS, ids=[s.name for s in SPECS])
@given(data=st.data())
def test_a_wrong_argument_ends_in_one_of_our_errors(spec: Spec, data) -> None:
    argument = data.draw(st.sampled_from(sorted(spec.args)), label="argument")
    kwargs = {name: make() for name, make in spec.args.items()}
    if argument in spec.arrays:
        wrong = data.draw(st.one_of(anything, perturbed(kwargs[argument])), label="value")
    else:
        wrong = data.draw(anything, label="value")
    kwargs[argument] = wrong
    _call(spec, kwargs)


FORMS = {
    "list": lambda a: np.asarray(a).tolist(),
    "tuple": lambda a: (
        tuple(map(tuple, np.asarray(a).tolist()))
        if np.ndim(a) == 2
        else tuple(np.asarray(a).tolist())
    ),
    "C-order copy": lambda a: np.ascontiguousarray(np.asarray(a)),
    "Fortran order": lambda a: np.asfortranarray(np.asarray(a)),
    "ints where whole": lambda a: (
        np.asarray(a).astype(int) if np.all(np.asarray(a) == np.round(a)) else np.asarray(a)
    ),
}


WITH_FORMS = [s for s in SPECS if s.forms]


@pytest.mark.parametrize("spec", WITH_FORMS, ids=[s.name for s in WITH_FORMS])
@given(argument=st.data(), form=st.sampled_from(sorted(FORMS)))
def test_an_argument_in_another_form_gives_the_same_result(spec: Spec, argument, form: str):
    name = argument.draw(st.sampled_from(spec.forms), label="argument")
    kwargs = {n: make() for n, make in spec.args.items()}
    seen(spec.name)
    want = spec.result(spec.call(**kwargs))
    kwargs = {n: make() for n, make in spec.args.items()}
    kwargs[name] = FORMS[form](kwargs[name])
    got = spec.result(spec.call(**kwargs))
    for g, w in zip(got, want, strict=True):
        np.testing.assert_array_equal(g, w)
