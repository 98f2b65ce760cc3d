"""Embarrassingly parallel studies: one task per run, on local cores or a Dask cluster.

Monte Carlo studies (`ekfslam.analysis.consistency.compare`, `robustness.outlier_study`,
`association_stress.stress_study`) and noise sweeps (`mrclam_tuning.tune_noise`) are lists of
independent tasks. `run_tasks` maps a module-level function over them through joblib: in this
process (jobs=1), on local processes (jobs=N, or None for every core; joblib's loky backend), or
on a Dask cluster (`dask="tcp://host:8786"`, joblib's dask backend; needs the optional extra,
``pip install -e '.[dask]'`` from a checkout: the package is not on PyPI). Every task carries
its own seed, fixed before dispatch, and the results come back in the tasks' order, so a study
gives the same numbers whatever the backend.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import joblib

from ekfslam.errors import ConfigError

#: seconds to wait for a Dask scheduler to answer before giving up
DASK_TIMEOUT = 10.0


def run_tasks(
    fn: Callable[..., Any],
    tasks: Iterable[tuple],
    jobs: int | None = 1,
    dask: str | None = None,
) -> list[Any]:
    """[fn(*task) for task in tasks], possibly in parallel; results in the tasks' order.

    fn : a module-level function (it is pickled to the workers), pure given its arguments.
    jobs : 1 runs in this process, N on N local processes, None on every local core.
    dask : a Dask scheduler's address (``tcp://...``, or a LocalCluster's ``inproc://``);
        jobs is then ignored, the cluster's workers decide.
    """
    tasks = list(tasks)
    if jobs is not None and jobs < 1:
        raise ConfigError(f"jobs must be at least 1 (or None: every core), got {jobs}")
    if dask is not None:
        return _on_dask(fn, tasks, dask)
    if jobs == 1 or len(tasks) <= 1:
        return [fn(*task) for task in tasks]
    return joblib.Parallel(n_jobs=-1 if jobs is None else jobs)(
        joblib.delayed(fn)(*task) for task in tasks
    )


def _on_dask(fn: Callable[..., Any], tasks: list[tuple], address: str) -> list[Any]:
    try:
        from distributed import Client  # lazy: optional extra ekfslam[dask], 1 s to import
    except ImportError:
        raise ConfigError(
            f"--dask {address}: dask.distributed is not installed "
            "(from the checkout: pip install -e '.[dask]')"
        ) from None
    try:
        client = Client(address, timeout=DASK_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(
            f"--dask {address}: no Dask scheduler answered ({' '.join(str(exc).split())})"
        ) from None
    with client, joblib.parallel_config(backend="dask"):
        return joblib.Parallel()(joblib.delayed(fn)(*task) for task in tasks)
