"""``FilterConfig(backend="auto")`` compiles a workload, not a replay: twenty short replays are a
long run, and the package's own batches (Monte Carlo, noise fit, error budget, sweeps) say how
many replays they make (`pipeline.batch_config`), so that notebooks 07-09 do not replay each
short run as Python; and, while the compiled steps are not in the cache, a replay runs on the
Python steps unless compiling would cost less than it (`backend.for_replay`)."""

from __future__ import annotations

import dataclasses
import sys

import pytest

from ekfslam import pipeline
from ekfslam.analysis import association_stress, consistency, error_budget, laps, noise_fit
from ekfslam.core.association import AssociationConfig
from ekfslam.core.filter import backend
from ekfslam.core.filter.config import COMPILE_ABOVE_EVENTS, FilterConfig
from ekfslam.core.models import ODOMETRY, RANGE_BEARING
from ekfslam.core.noise import default_noise
from ekfslam.errors import ConfigError
from ekfslam.strategies import PYTHON_COST


@pytest.fixture
def chosen(monkeypatch) -> list[tuple[int, str]]:
    """(events, backend) of every "auto" the replays resolve, the compiled steps cached."""
    seen: list[tuple[int, str]] = []
    real = backend.for_replay
    monkeypatch.setattr(backend, "compiled_ready", lambda motion, sensor: True)

    def recording(config: FilterConfig, events: int) -> FilterConfig:
        out = real(config, events)
        if config.backend == "auto":
            seen.append((events, out.backend))
        return out

    monkeypatch.setattr(pipeline, "for_replay", recording)
    return seen


@pytest.mark.parametrize(
    ("events", "ready", "expected"),
    [
        (COMPILE_ABOVE_EVENTS // 2, False, "python"),  # short: never worth loading
        (COMPILE_ABOVE_EVENTS + 1, True, "numba"),
        (COMPILE_ABOVE_EVENTS + 1, False, "python"),  # cold: a minute's compile for 0.5 s
        (backend.COMPILE_COLD_ABOVE_EVENTS, False, "python"),
        (backend.COMPILE_COLD_ABOVE_EVENTS + 1, False, "numba"),  # the compile pays, cold too
    ],
)
def test_a_cold_cache_keeps_a_replay_on_the_python_steps_unless_compiling_pays(
    monkeypatch, events, ready, expected
) -> None:
    """Regression (issue 37): notebooks 07-10 and 12 took 45-56 s on a fresh machine against
    5-19 s warm, their first long replay compiling the steps in the notebook's kernel."""
    asked: list[tuple] = []

    def compiled_ready(motion, sensor) -> bool:
        asked.append((motion, sensor))
        return ready

    monkeypatch.setattr(backend, "compiled_ready", compiled_ready)
    assert backend.for_replay(FilterConfig(), events).backend == expected
    named = FilterConfig(backend="numba")
    assert backend.for_replay(named, COMPILE_ABOVE_EVENTS // 2) is named  # a name is kept
    assert all(models == (ODOMETRY, RANGE_BEARING) for models in asked)


def test_a_cold_cache_starts_the_seed_models_compiling_once_in_another_process(
    monkeypatch, tmp_path
) -> None:
    started: list[list[str]] = []
    monkeypatch.setattr(backend, "_loaded", set())
    monkeypatch.setattr(backend, "_warming", set())
    monkeypatch.setattr(backend.subprocess, "Popen", lambda argv, **kw: started.append(argv))
    monkeypatch.setattr(backend, "_warm_stamp", lambda motion, sensor: tmp_path / "cold.stamp")
    assert not backend.compiled_ready(ODOMETRY, RANGE_BEARING)
    assert not backend.compiled_ready(ODOMETRY, RANGE_BEARING)
    assert started == [[sys.executable, *backend.WARMER]]  # once, not per replay
    (tmp_path / "cold.stamp").touch()  # the other process is done
    assert backend.compiled_ready(ODOMETRY, RANGE_BEARING)


def test_replays_together_decide_the_backend(square, chosen) -> None:
    events = pipeline.schedule(square, default_noise(square)).events
    many = COMPILE_ABOVE_EVENTS // events + 1
    config = pipeline.batch_config(square, many)
    alone, batch = pipeline.replay(square), pipeline.replay(square, config=config)
    assert chosen == [(events * many, "numba"), (events, "python")]  # the named one: as it is
    assert config.backend == "numba" and pipeline.batch_config(square, 1).backend == "python"
    assert batch.counts == alone.counts  # the same filter, compiled
    assert abs(batch.mu - alone.mu).max() < 1e-9


def test_a_batch_keeps_a_backend_named(square) -> None:
    named = FilterConfig(backend="python")
    assert pipeline.batch_config(square, 10**6, named) is named


@pytest.mark.parametrize("bad", [0, -3, 1.5, True, "20", None])
def test_a_batch_is_a_whole_number_of_at_least_one_replay(square, bad) -> None:
    with pytest.raises(ConfigError, match="batch_config: count must be a whole number >= 1"):
        pipeline.batch_config(square, bad)


def counted(monkeypatch, module) -> list[int]:
    """Every count the module's batches were resolved for (`pipeline.batch_config`)."""
    seen: list[int] = []
    real = pipeline.batch_config

    def recording(run, count, *args, **kwargs):
        seen.append(count)
        return real(run, count, *args, **kwargs)

    monkeypatch.setattr(module, "batch_config", recording)
    return seen


def test_a_monte_carlo_counts_every_run_of_every_linearization(monkeypatch) -> None:
    seen = counted(monkeypatch, consistency)
    consistency.compare("octagon", runs=3, linearizations=("standard", "fej"))
    assert seen == [6] * 6


def test_an_error_budget_counts_its_rows_and_seeds(monkeypatch) -> None:
    seen = counted(monkeypatch, error_budget)
    error_budget.error_budget("square", sources=("wheel slip",), seeds=(1, 2))
    assert seen == [(2 + 2 * 1) * 2] * 8


def test_a_noise_fit_counts_its_search(monkeypatch, square) -> None:
    seen = counted(monkeypatch, noise_fit)
    noise_fit.fit_noise(square, default_noise(square), FilterConfig(), max_evaluations=12)
    assert seen == [12]  # the search and the two replays after it, one batch


def test_a_sweep_counts_its_points(monkeypatch) -> None:
    seen = counted(monkeypatch, laps)
    laps.size_sweep(("square",), sizes=(0.7, 1.0), seeds=(1,))
    assert seen == [2, 2]


def test_a_stress_study_counts_its_methods_and_seeds(monkeypatch) -> None:
    seen = counted(monkeypatch, association_stress)
    association_stress.stress_study(runs=1)
    assert seen == [len(association_stress.METHODS)] * len(association_stress.METHODS)


@pytest.mark.parametrize(
    ("method", "backend"), [("nn", "python"), ("jcbb", "python"), ("mht", "numba")]
)
def test_an_association_weighs_the_events_by_its_work(octagon_run, chosen, method, backend):
    """On the octagon's 1,928 events, the Python steps take 0.18 s with nn and 0.4 s with jcbb
    (less than loading the compiled ones), 4 s with mht's 8 hypotheses (0.7 s compiled)."""
    events = pipeline.schedule(octagon_run, default_noise(octagon_run)).events
    pipeline.replay(octagon_run, association=AssociationConfig(method=method))
    hypotheses = AssociationConfig().hypotheses if method == "mht" else 1
    assert chosen == [(events * PYTHON_COST[method] * hypotheses, backend)]


@pytest.fixture(scope="module")
def octagon_run():
    from ekfslam.logs.runlog import read_run
    from ekfslam.places import seed_runs_dir

    return read_run(seed_runs_dir() / "octagon-2laps")


def test_a_users_models_on_a_cold_cache_say_once_how_to_compile_them(
    monkeypatch, tmp_path, capsys
) -> None:
    started: list = []
    monkeypatch.setattr(backend, "_loaded", set())
    monkeypatch.setattr(backend, "_warming", set())
    monkeypatch.setattr(backend.subprocess, "Popen", lambda argv, **kw: started.append(argv))
    monkeypatch.setattr(backend, "_warm_stamp", lambda motion, sensor: tmp_path / "cold.stamp")
    sensor = dataclasses.replace(RANGE_BEARING, name="my camera")
    assert not backend.compiled_ready(ODOMETRY, sensor)
    assert not backend.compiled_ready(ODOMETRY, sensor)
    said = capsys.readouterr().err.splitlines()
    assert said == [
        "ekfslam: the odometry and my camera models run on the Python steps; "
        'FilterConfig(backend="numba") compiles them (a minute or more, once per machine)'
    ]
    assert started == []  # only the seed's models compile by themselves
