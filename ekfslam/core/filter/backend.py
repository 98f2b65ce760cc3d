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

import functools
import importlib
import types
from collections.abc import Callable

from ekfslam.core.filter import iterated, jcbb_search, predictions, steps
from ekfslam.core.filter.rebinding import interpreted, rebind
from ekfslam.core.models import MotionModel, SensorModel

#: The functions a filter runs, by the names it calls them.
ROOTS: dict[str, Callable] = {
    "predict": steps.predict,
    "correct": steps.correct,
    "sight": steps.sight,
    "feed": steps.feed,
    "linearisation_point": steps.linearisation_point,
    "place_landmark": steps.place_landmark,
    "record_observation": steps.record_observation,
    "settle": steps.settle,
    "linearise": iterated.linearise,
    "nearest": predictions.nearest,
    "predict_all": predictions.predict_all,
    "search": jcbb_search.search,
}

#: The backends (`ekfslam.core.filter.config.FilterConfig.backend` chooses).
BACKENDS = ("python", "numba")

#: The compiled backend: imported only when asked for, since it loads numba and its cache.
COMPILER = "ekfslam.core.filter.compile"


@functools.cache
def steps_for(motion: MotionModel, sensor: SensorModel, backend: str) -> types.SimpleNamespace:
    """The filter's step functions (`ROOTS`) for these models on this backend, made once."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    models = {"motion": motion, "sensor": sensor}
    if backend == "python":
        return rebind(ROOTS, models, interpreted)
    return importlib.import_module(COMPILER).compiled(ROOTS, models)
