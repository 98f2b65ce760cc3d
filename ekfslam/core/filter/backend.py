"""Which implementation of the filter's steps runs: the readable functions themselves, or the same
functions compiled by numba, each bound to the filter's motion and sensor models.

The steps (`ekfslam.core.filter.steps`, `iterated`, `predictions`, `jcbb_search`) call the
models as ``motion.f(...)``, ``sensor.h(...)``: names their module binds to the seed's models
(`ekfslam.core.models.ODOMETRY`, `RANGE_BEARING`). `steps_for` gives the steps for other models
by binding those names again, in copies of the functions (and of every function of ekfslam they
call, down to the models), and, for the ``"numba"`` backend, compiles the copies
(`ekfslam.core.filter.compile`, the only module that imports numba). No file is edited and
nothing is written twice: a new sensor model is a `SensorModel` handed to `FilterConfig`.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import subprocess
import sys
import types
from collections.abc import Callable
from pathlib import Path

from ekfslam.core.filter import iterated, jcbb_search, predictions, steps
from ekfslam.core.filter.config import FilterConfig, backend_for
from ekfslam.core.filter.rebinding import interpreted, rebind
from ekfslam.core.models import ODOMETRY, RANGE_BEARING, MotionModel, SensorModel

#: The functions a filter runs, by the names it calls them.
ROOTS: dict[str, Callable] = {
    "predict": steps.predict,
    "correct": steps.correct,
    "sight": steps.sight,
    "feed": steps.feed,
    "linearisation_point": steps.linearisation_point,
    "place_landmark": steps.place_landmark,
    "set_landmark": steps.set_landmark,
    "record_observation": steps.record_observation,
    "settle": steps.settle,
    "linearise": iterated.linearise,
    "nearest": predictions.nearest,
    "predict_all": predictions.predict_all,
    "search": jcbb_search.search,
    "option_likelihoods": jcbb_search.option_likelihoods,
}

#: The backends (`ekfslam.core.filter.config.FilterConfig.backend` chooses).
BACKENDS = ("python", "numba")

#: The compiled backend: imported only when asked for, since it loads numba and its cache.
COMPILER = "ekfslam.core.filter.compile"


#: With backend "auto", a filter's models run this many events (predictions and sightings) in a
#: process on the Python steps before the compiled ones are loaded: loading takes about a second
#: (numba and the cached machine code), which the compiled steps win back in as many events at
#: the 100-200 µs a Python correction costs against a few µs compiled.
COMPILE_AFTER_EVENTS = 5_000

#: The command that compiles the seed's models in a process of its own (`auto_steps`):
#: ``python -m ekfslam warm`` (`ekfslam.cli.warm`).
WARMER = ("-m", "ekfslam", "warm", "--quiet")

#: With backend "auto", a replay (or a batch of them) long enough for the compiled steps whose
#: machine code is not in the cache yet runs on the Python steps (the cache compiled meanwhile in
#: a process of its own, `auto_steps`' message) unless its work is more than this many events:
#: compiling takes 40-60 s, which the Python steps spend on about a million events (the octagon's
#: 1,928 in 88 ms: 46 µs an event, `ekfslam.strategies.PYTHON_COST`).
COMPILE_COLD_ABOVE_EVENTS = 1_000_000

_events: dict[tuple[MotionModel, SensorModel], int] = {}  # per models: events run in Python
_look_again: dict[tuple[MotionModel, SensorModel], int] = {}  # ... when the cache is looked at
_loaded: set[tuple[MotionModel, SensorModel]] = set()  # compiled steps loaded in this process
_warming: set[tuple[MotionModel, SensorModel]] = set()  # compiled in another process, now


def models_of(motion: MotionModel, sensor: SensorModel) -> dict[str, object]:
    """The names the steps call their models by, bound to these models."""
    return {"motion": motion, "sensor": sensor}


def auto_steps(
    motion: MotionModel, sensor: SensorModel, events: int
) -> types.SimpleNamespace | None:
    """What backend "auto" runs, asked by a filter that ran `events` more events on the Python
    steps: the compiled steps once these models have run `COMPILE_AFTER_EVENTS` events in the
    process and the cache holds their machine code (`compile.warm_stamp`), else None (the
    Python steps, as they are).

    When the cache is cold, the seed's models are compiled in a process of their own
    (``python -m ekfslam warm``, about a minute, once per machine) while the Python steps run,
    with a one-line message; other models stay on the Python steps (name backend "numba" to
    compile them in this process)."""
    key = (motion, sensor)
    if key in _loaded:
        return steps_for(motion, sensor, "numba")
    total = _events[key] = _events.get(key, 0) + events
    if total < max(COMPILE_AFTER_EVENTS, _look_again.get(key, 0)):
        return None
    _look_again[key] = total + COMPILE_AFTER_EVENTS
    return steps_for(motion, sensor, "numba") if compiled_ready(motion, sensor) else None


def for_replay(config: FilterConfig, events: int) -> FilterConfig:
    """`config` with backend "auto" resolved for a replay of `events` weighed events
    (`ekfslam.core.filter.config.backend_for`: compiled above `COMPILE_ABOVE_EVENTS`), on the
    Python steps when their machine code is not cached yet and compiling it would cost more than
    the replay (`COMPILE_COLD_ABOVE_EVENTS`): a notebook's first replay does not wait a minute
    for the compiler (issue 37)."""
    resolved = backend_for(config, events)
    if config.backend != "auto" or resolved.backend != "numba":
        return resolved
    motion, sensor = config.motion or ODOMETRY, config.sensor or RANGE_BEARING
    if events > COMPILE_COLD_ABOVE_EVENTS or compiled_ready(motion, sensor):
        return resolved
    return dataclasses.replace(resolved, backend="python")


def compiled_ready(motion: MotionModel, sensor: SensorModel) -> bool:
    """Whether the compiled steps for these models run without compiling first (loaded in this
    process, or their machine code in the cache: `compile.warm_stamp`). When they do not, the
    seed's models are compiled in a process of its own (``python -m ekfslam warm``, about a
    minute, once per machine) with a one-line message; other models are compiled only where
    backend "numba" is named."""
    key = (motion, sensor)
    if key in _loaded:
        return True
    if _warm_stamp(motion, sensor).exists():
        _loaded.add(key)
        return True
    if key == (ODOMETRY, RANGE_BEARING) and key not in _warming:
        _warming.add(key)
        subprocess.Popen(  # this interpreter, a module of ours
            [sys.executable, *WARMER],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        print(
            "ekfslam: compiling the filter's steps in the background (once per machine, about "
            "a minute); the Python steps run until then",
            file=sys.stderr,
        )
    elif key != (ODOMETRY, RANGE_BEARING) and key not in _warming:
        _warming.add(key)  # said once: a model of the user's is compiled only when asked
        print(
            f"ekfslam: the {motion.name} and {sensor.name} models run on the Python steps; "
            'FilterConfig(backend="numba") compiles them (a minute or more, once per machine)',
            file=sys.stderr,
        )
    return False


@functools.cache
def _warm_stamp(motion: MotionModel, sensor: SensorModel) -> Path:
    """`compile.warm_stamp` of these models, named once a process: naming it digests every
    source the steps run (about 50 ms), asked again at each long replay while the cache is cold."""
    return importlib.import_module(COMPILER).warm_stamp(ROOTS, models_of(motion, sensor))


@functools.cache
def steps_for(motion: MotionModel, sensor: SensorModel, backend: str) -> types.SimpleNamespace:
    """The filter's step functions (`ROOTS`) for these models on this backend, made once."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    models = models_of(motion, sensor)
    if backend == "python":
        return rebind(ROOTS, models, interpreted)
    return importlib.import_module(COMPILER).compiled(ROOTS, models)
