"""The studies give the same numbers in this process, on two local processes and on Dask."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ekfslam.analysis import association_stress
from ekfslam.analysis.consistency import compare
from ekfslam.analysis.mrclam_consistency import mrclam_consistency
from ekfslam.analysis.parallel import run_tasks
from ekfslam.errors import ConfigError
from tests.approx import ABS, REL, approx_tree


def _square_plus(x: int, y: int) -> int:
    return x * x + y


def test_run_tasks_keeps_the_order_in_and_out_of_process():
    tasks = [(i, 10 * i) for i in range(7)]
    want = [i * i + 10 * i for i in range(7)]
    assert run_tasks(_square_plus, tasks, jobs=1) == want
    assert run_tasks(_square_plus, tasks, jobs=2) == want


def test_run_tasks_refuses_zero_jobs():
    with pytest.raises(ConfigError, match="jobs must be at least 1"):
        run_tasks(_square_plus, [(1, 2)], jobs=0)


def _same_consistency(a, b) -> None:
    """Every field but the timing is equal, arrays element by element (NaN where NaN), floats
    to 1e-9: each process may run the compiled or the Python steps, by its compile cache."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "seconds":
            continue
        if isinstance(x, np.ndarray) and x.dtype.kind == "f":
            np.testing.assert_allclose(x, y, rtol=REL, atol=ABS, err_msg=f.name)
        elif isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        else:
            assert approx_tree(x) == y, f.name


def test_monte_carlo_is_the_same_on_one_and_two_processes():
    one = compare("octagon", 3, ("standard", "fej"), first_seed=5, jobs=1)
    two = compare("octagon", 3, ("standard", "fej"), first_seed=5, jobs=2)
    assert [r.linearization for r in two] == ["standard", "fej"]
    assert two[0].runs == 3 and len(two[0].map_nees) == 3
    for a, b in zip(one, two, strict=True):
        _same_consistency(a, b)
    # the runs differ from one another, so an order mix-up would show
    assert len(set(one[0].map_nees.tolist())) == 3


def test_stress_study_is_the_same_on_one_and_two_processes():
    one = association_stress.stress_study(2, 2, jobs=1)
    two = association_stress.stress_study(2, 2, jobs=2)
    assert one.seeds == two.seeds == [2, 3]
    assert one.cases == two.cases
    assert one.detections == two.detections
    assert sorted(two.wrong) == ["jcbb", "nn"]
    for m in two.wrong:
        np.testing.assert_array_equal(one.wrong[m], two.wrong[m])
    np.testing.assert_allclose(one.path, two.path, rtol=REL, atol=ABS)


@pytest.mark.slow
def test_monte_carlo_is_the_same_on_a_dask_cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster:
        on_dask = compare(
            "octagon", 3, ("standard", "fej"), first_seed=5, dask=cluster.scheduler_address
        )
        stress = association_stress.stress_study(2, 2, dask=cluster.scheduler_address)
    here = compare("octagon", 3, ("standard", "fej"), first_seed=5, jobs=1)
    for a, b in zip(here, on_dask, strict=True):
        _same_consistency(a, b)
    assert stress.cases == association_stress.stress_study(2, 2, jobs=1).cases


@pytest.mark.shared_data
def test_mrclam_robots_are_the_same_on_one_and_two_processes(mrclam7):
    one = mrclam_consistency(mrclam7, "map", (2, 4), ("standard", "fej"), jobs=1)
    two = mrclam_consistency(mrclam7, "map", (2, 4), ("standard", "fej"), jobs=2)
    assert [(r.robot, r.linearization) for r in two.runs] == [
        (2, "standard"),
        (2, "fej"),
        (4, "standard"),
        (4, "fej"),
    ]
    # each process may run other steps (compiled or Python, by its compile cache): equal to 1e-9
    assert approx_tree(one.as_dict()) == two.as_dict()
    for a, b in zip(one.runs, two.runs, strict=True):
        np.testing.assert_allclose(a.nees, b.nees, rtol=REL, atol=ABS)
        np.testing.assert_allclose(a.error, b.error, rtol=REL, atol=ABS)
