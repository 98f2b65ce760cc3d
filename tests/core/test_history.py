"""Tests of ekfslam.core.filter.history: the outcome codes and the named columns of a row."""

from __future__ import annotations

import ast
import inspect
import math
from dataclasses import fields

import numpy as np
import pytest

from ekfslam.core.filter import steps
from ekfslam.core.filter.config import FilterConfig, FilterCounts
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter.history import (
    OBS_COLUMNS,
    OBS_ROW,
    ROW,
    ROW_COLUMNS,
    Outcome,
    obs_columns,
    obs_row,
    obs_width,
)


def test_every_outcome_the_correction_returns_is_a_member() -> None:
    tree = ast.parse(inspect.getsource(steps.correct))
    returned = {ast.unparse(node.value) for node in ast.walk(tree) if isinstance(node, ast.Return)}
    assert returned == {  # a member's code: compiled, a member would be rebuilt at each return
        "Outcome.ACCEPTED.value",
        "Outcome.REJECTED.value",
        "Outcome.REFUSED.value",
        "Outcome.SINGULAR.value",
    }


def test_the_codes_are_0_to_6_so_a_code_indexes_the_members() -> None:
    assert [int(o) for o in Outcome] == list(range(len(Outcome)))
    assert [o.label for o in Outcome] == [
        "initialised",
        "accepted",
        "rejected",
        "refused",
        "reinitialised",
        "singular",
        "deferred",
    ]


def test_filter_counts_has_one_field_per_outcome_label() -> None:
    assert [f.name for f in fields(FilterCounts)] == ["predictions"] + [o.label for o in Outcome]
    counts = FilterCounts(predictions=9, **{o.label: 10 + o for o in Outcome})
    assert [counts.of(o) for o in Outcome] == [10, 11, 12, 13, 14, 15, 16]


def test_every_outcome_the_filter_records_is_a_member_and_counted() -> None:
    f = EKFSLAM([0.0, 0.0, 0.0])
    Q = np.diag([1e-4, 1e-4])
    returned = [
        f.update(1, (0.0, 0.3), Q),  # on the robot: refused
        f.update(2, (1.0, 0.2), Q),  # initialised
        f.update(2, (1.0, 0.2), Q),  # accepted
        f.update(2, (1.6, 0.2), Q),  # rejected by the gate
        f.update(2, (1.0, 0.2), 1e300 * np.eye(2)),  # S overflows: singular
    ]
    assert all(type(o) is Outcome for o in returned)
    h = f.history()
    assert (
        [Outcome(k) for k in h.obs_outcome.tolist()]
        == returned
        == [
            Outcome.REFUSED,
            Outcome.INITIALISED,
            Outcome.ACCEPTED,
            Outcome.REJECTED,
            Outcome.SINGULAR,
        ]
    )
    for o in Outcome:
        assert f.counts.of(o) == returned.count(o) == int(h.outcome_mask(o).sum())


@pytest.mark.parametrize("backend", ["python", "numba"])
def test_the_seed_initialisation_records_its_own_outcome_not_the_corrections(backend) -> None:
    # init="seed" places a landmark and corrects with the same sighting (`steps.sight`, which
    # records ACCEPTED): the history and the counts say INITIALISED, and REINITIALISED for a
    # landmark placed again after three rejected sightings that agree
    f = EKFSLAM([0.0, 0.0, 0.0], config=FilterConfig(init="seed", backend=backend))
    Q = np.diag([1e-4, 1e-4])
    returned = [f.update(2, (1.0, 0.2), Q) for _ in range(2)]
    returned += [f.update(2, (1.6, 0.2), Q) for _ in range(3)]
    expected = [Outcome.INITIALISED, Outcome.ACCEPTED, *[Outcome.REJECTED] * 2]
    assert returned == [*expected, Outcome.REINITIALISED]
    h = f.history()
    assert [Outcome(k) for k in h.obs_outcome.tolist()] == returned
    assert [f.counts.of(o) for o in Outcome] == [returned.count(o) for o in Outcome]
    assert np.isfinite(h.obs_nis[[0, 1, 2, 3]]).all()  # the seed's placing is an update too
    assert np.allclose(h.obs_landmark[-1], f.landmark(2)[0])


def test_the_named_columns_cover_each_row_once() -> None:
    def covered(columns) -> list[int]:
        out: list[int] = []
        for c in columns:
            out += range(c.start, c.stop) if isinstance(c, slice) else [c]
        return out

    assert covered(ROW_COLUMNS) == list(range(len(ROW)))
    assert sorted(covered(OBS_COLUMNS)) == list(range(len(OBS_ROW)))
    for size in (1, 2, 3):  # a measurement of any size: z, ẑ, ν of `size`, S of size²
        columns = obs_columns(size)
        assert sorted(covered(columns)) == list(range(obs_width(size)))
        assert len(obs_row(size)[columns.S]) == size * size
    assert OBS_ROW[OBS_COLUMNS.z_hat] == ("z_hat0", "z_hat1")
    assert OBS_ROW[OBS_COLUMNS.S] == ("S00", "S01", "S10", "S11")
    assert OBS_ROW[OBS_COLUMNS.outcome] == "outcome"


def test_the_recorded_observation_fields_come_from_their_named_columns() -> None:
    f = EKFSLAM([0.0, 0.0, 0.0])
    Q = np.diag([1e-4, 4e-4])
    f.update(3, (1.0, 0.2), Q)
    f.update(3, (1.02, 0.21), Q, t=0.5)
    h = f.history()
    assert h.obs_t.tolist() == [0.0, 0.5] and h.obs_id.tolist() == [3, 3]
    np.testing.assert_array_equal(h.obs_z[1], [1.02, 0.21])
    assert np.isnan(h.obs_z_hat[0]).all() and np.isnan(h.obs_nis[0])  # a new landmark
    np.testing.assert_allclose(h.obs_z_hat[1], [1.0, 0.2], atol=1e-12)
    np.testing.assert_allclose(h.obs_innovation[1], [0.02, 0.01], atol=1e-12)
    S = h.obs_S[1]
    assert S[0, 1] == S[1, 0] and S[0, 0] > Q[0, 0] and S[1, 1] > Q[1, 1]
    nu = h.obs_innovation[1]
    assert math.isclose(h.obs_nis[1], float(nu @ np.linalg.solve(S, nu)), rel_tol=1e-12)
    mean, cov = f.landmark(3)
    np.testing.assert_array_equal(h.obs_landmark[1], mean)
    np.testing.assert_array_equal(h.obs_landmark_cov[1], cov)
