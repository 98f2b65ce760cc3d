"""detections.csv's optional sigma_range,sigma_bearing columns: read, written, checked, and
replayed as each sighting's own Q (issue 26)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ekfslam.core.association import AssociationConfig
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.noise import NoiseConfig
from ekfslam.errors import InputError
from ekfslam.logs.edit import truncate
from ekfslam.logs.runlog import Detections, read_run, write_run
from ekfslam.pipeline import replay, schedule

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


def _with_sigmas(run, sigma_range, sigma_bearing):
    d = run.detections
    n = len(d.t)
    return dataclasses.replace(
        run,
        detections=dataclasses.replace(
            d,
            sigma_range=np.broadcast_to(np.asarray(sigma_range, dtype=float), (n,)).copy(),
            sigma_bearing=np.broadcast_to(np.asarray(sigma_bearing, dtype=float), (n,)).copy(),
        ),
    )


@pytest.fixture(scope="module")
def square():
    return read_run(RUNS / "square-2laps")


def test_the_columns_are_written_and_read_back_bit_for_bit(square, tmp_path: Path) -> None:
    n = len(square.detections.t)
    run = _with_sigmas(square, np.linspace(0.01, 0.05, n), np.linspace(0.02, 0.03, n))
    write_run(run, tmp_path / "run")
    header = (tmp_path / "run" / "detections.csv").read_text().splitlines()[0]
    assert header == "t,tag_id,range,bearing,sigma_range,sigma_bearing"
    back = read_run(tmp_path / "run")
    np.testing.assert_array_equal(back.detections.sigma_range, run.detections.sigma_range)
    np.testing.assert_array_equal(back.detections.sigma_bearing, run.detections.sigma_bearing)
    write_run(square, tmp_path / "plain")  # without them, the four columns as before
    assert (
        (tmp_path / "plain" / "detections.csv").read_text().startswith("t,tag_id,range,bearing\n")
    )
    assert read_run(tmp_path / "plain").detections.sigma_range is None


@pytest.mark.parametrize(
    ("cell", "problem"),
    [
        ("0.0", "sigma_range 0.0 is not positive"),
        ("nan", "sigma_range is nan"),
        ("x", "not a number"),
    ],
)
def test_a_bad_sigma_is_one_error_at_its_line(square, tmp_path: Path, cell, problem) -> None:
    write_run(_with_sigmas(square, 0.02, 0.02), tmp_path / "run")
    path = tmp_path / "run" / "detections.csv"
    lines = path.read_text().splitlines()
    fields = lines[3].split(",")
    fields[4] = cell
    lines[3] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as err:
        read_run(tmp_path / "run")
    assert err.value.line == 4 and problem in str(err.value)


def test_one_sigma_column_without_the_other_is_refused(square, tmp_path: Path) -> None:
    write_run(square, tmp_path / "run")
    path = tmp_path / "run" / "detections.csv"
    text = path.read_text().replace(
        "t,tag_id,range,bearing", "t,tag_id,range,bearing,sigma_range", 1
    )
    path.write_text(text)
    with pytest.raises(InputError, match="header"):
        read_run(tmp_path / "run")
    half = dataclasses.replace(square.detections, sigma_range=np.ones(len(square.detections.t)))
    with pytest.raises(InputError, match="both sigma_range and sigma_bearing"):
        write_run(dataclasses.replace(square, detections=half), tmp_path / "half")


def test_sigmas_equal_to_the_noise_replay_as_the_noise_alone(square) -> None:
    noise = NoiseConfig()
    plain = replay(square, noise)
    same = replay(_with_sigmas(square, noise.sigma_range, noise.sigma_bearing), noise)
    np.testing.assert_allclose(plain.mu, same.mu, rtol=1e-12, atol=1e-15)  # two routes: round-off
    np.testing.assert_allclose(plain.Sigma, same.Sigma, rtol=1e-12, atol=1e-18)


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_each_sighting_is_updated_with_its_own_q(seed) -> None:
    run = read_run(RUNS / "square-2laps")
    run = truncate(run, float(run.detections.t[40]))
    rng = np.random.default_rng(seed)
    n = len(run.detections.t)
    s_r, s_b = rng.uniform(0.005, 0.2, n), rng.uniform(0.005, 0.2, n)
    noisy = _with_sigmas(run, s_r, s_b)
    got = replay(noisy, NoiseConfig(), noisy.meta.filter_defaults)
    steps = schedule(run, NoiseConfig())
    upto, us, dts, ends, M, R = steps.upto, steps.u, steps.dt, steps.t, steps.M, steps.R
    det_id, det_time, det_z = steps.ids, steps.times, steps.z
    # each Q as the replay builds them (a 2x2 matmul may round its last bit otherwise, by the
    # memory alignment of its operands): their values are diag(σ_r², σ_φ²), checked here
    each = NoiseConfig().sighting_Q(run.detections.range, s_r, s_b)
    np.testing.assert_allclose(each[:, 0, 0], s_r**2, rtol=1e-15, atol=0)
    np.testing.assert_allclose(each[:, 1, 1], s_b**2, rtol=1e-15, atol=0)
    np.testing.assert_array_equal(each[:, 0, 1], 0.0)
    ekf = EKFSLAM(run.meta.nominal_start)
    done = 0
    for i, p in enumerate(upto):
        if p > done:
            ekf.predict_many(us[done:p], dts[done:p], ends[done:p], M, R)
            done = p
        ekf.update(det_id[i], det_z[i], each[i], det_time[i])
    if done < len(us):
        ekf.predict_many(us[done:], dts[done:], ends[done:], M, R)
    np.testing.assert_allclose(got.mu, ekf.mu, rtol=1e-12, atol=1e-15)  # two routes: round-off
    np.testing.assert_allclose(got.Sigma, ekf.Sigma, rtol=1e-12, atol=1e-18)
    ignored = replay(noisy, NoiseConfig(per_sighting=False))
    np.testing.assert_allclose(ignored.mu, replay(run, NoiseConfig()).mu, rtol=1e-12, atol=1e-15)


def test_a_range_dependent_sigma_trusts_near_sightings_more(square) -> None:
    flat = replay(square, NoiseConfig(sigma_range=0.03))
    growing = replay(square, NoiseConfig(sigma_range=0.01, sigma_range_per_m=0.02))
    h = growing.history
    ranges = h.obs_z[:, 0]
    tested = ~np.isnan(h.obs_nis)
    # S's range entry is H Σ Hᵀ + (0.01 + 0.02 r)²: it grows with r, beyond the flat replay's
    near, far = tested & (ranges < 0.6), tested & (ranges > 1.2)
    assert np.median(h.obs_S[near, 0, 0]) < np.median(flat.history.obs_S[near, 0, 0])
    assert np.median(h.obs_S[far, 0, 0]) > np.median(h.obs_S[near, 0, 0])


def test_with_hidden_ids_the_own_sigmas_are_not_used_and_it_says_so(square) -> None:
    noisy = _with_sigmas(square, 0.05, 0.05)
    with pytest.warns(RuntimeWarning, match="used with the ids known only"):
        replay(noisy, association=AssociationConfig(method="jcbb"))


def test_detections_built_by_position_have_no_sigmas() -> None:
    d = Detections(np.zeros(1), np.zeros(1, np.int64), np.ones(1), np.zeros(1))
    assert d.sigma_range is None and not d.has_sigmas
