"""Backend "auto" decides per use: a filter built directly starts on the Python steps and takes
the compiled ones once its models have run enough events in the process to pay for loading
them (`ekfslam.core.filter.backend.auto_steps`); a cold cache is compiled in another process
while the Python steps run. (Before, "auto" decided by a replay's event count, so every direct
use, a user's own loop, ran the Python steps: 5-10x slower.)"""

from __future__ import annotations

import numpy as np
import pytest

from ekfslam.core.filter import backend, state
from ekfslam.core.filter.ekf import EKFSLAM, FilterConfig
from ekfslam.core.models import ODOMETRY, RANGE_BEARING

Q, M = np.diag([0.01, 0.001]), np.diag([1e-3, 1e-4, 1e-4])


@pytest.fixture
def fresh(monkeypatch):
    """A process where the models have run nothing yet, and small thresholds."""
    for name in ("_events", "_look_again"):
        monkeypatch.setattr(backend, name, {})
    for name in ("_loaded", "_warming"):
        monkeypatch.setattr(backend, name, set())
    monkeypatch.setattr(backend, "COMPILE_AFTER_EVENTS", 60)
    monkeypatch.setattr(state, "LOOK_EVERY", 10)


def drive(f: EKFSLAM, first: int, last: int) -> None:
    """Steps first .. last - 1 of one run: a prediction and two sightings each."""
    for t in range(first, last):
        f.predict_many(np.array([[0.05, 0.0, 0.02]]), np.ones(1), np.array([float(t)]), M=M)
        for i, (r, b) in enumerate([(2.0, 0.3), (3.0, -1.0)]):
            f.update(i, np.array([r, b - 0.02 * t]), Q, float(t))


def test_a_direct_filter_takes_the_compiled_steps_once_they_pay(fresh, monkeypatch) -> None:
    monkeypatch.setattr(backend, "_warm_stamp", lambda motion, sensor: _Exists(True))
    python = backend.steps_for(ODOMETRY, RANGE_BEARING, "python")
    numba = backend.steps_for(ODOMETRY, RANGE_BEARING, "numba")
    f = EKFSLAM(np.zeros(3), config=FilterConfig(gate=None))
    assert f.steps is python
    drive(f, 1, 11)  # 30 events: not yet
    assert f.steps is python
    drive(f, 11, 41)  # past 60: compiled from here on
    assert f.steps is numba
    assert EKFSLAM(np.zeros(3)).steps is numba  # the next filter starts compiled
    reference = EKFSLAM(np.zeros(3), config=FilterConfig(gate=None, backend="python"))
    drive(reference, 1, 41)
    np.testing.assert_allclose(f.mu, reference.mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(f.Sigma, reference.Sigma, rtol=0, atol=1e-12)
    np.testing.assert_allclose(f.history().pose, reference.history().pose, rtol=0, atol=1e-9)


def test_a_cold_cache_compiles_elsewhere_while_the_python_steps_run(
    fresh, monkeypatch, capsys
) -> None:
    stamp = _Exists(False)
    monkeypatch.setattr(backend, "_warm_stamp", lambda motion, sensor: stamp)
    started = []
    monkeypatch.setattr(backend.subprocess, "Popen", lambda argv, **kw: started.append(argv))
    python = backend.steps_for(ODOMETRY, RANGE_BEARING, "python")
    f = EKFSLAM(np.zeros(3), config=FilterConfig(gate=None))
    drive(f, 1, 41)
    assert f.steps is python
    assert started == [[backend.sys.executable, "-m", "ekfslam", "warm", "--quiet"]]  # once
    assert "compiling the filter's steps in the background" in capsys.readouterr().err
    stamp.there = True  # the other process is done
    drive(f, 41, 81)
    assert f.steps is backend.steps_for(ODOMETRY, RANGE_BEARING, "numba")
    assert len(started) == 1


def test_a_named_backend_never_changes(fresh, monkeypatch) -> None:
    monkeypatch.setattr(backend, "_warm_stamp", lambda motion, sensor: _Exists(True))
    f = EKFSLAM(np.zeros(3), config=FilterConfig(gate=None, backend="python"))
    drive(f, 1, 41)
    assert f.steps is backend.steps_for(ODOMETRY, RANGE_BEARING, "python")


class _Exists:
    def __init__(self, there: bool) -> None:
        self.there = there

    def exists(self) -> bool:
        return self.there
