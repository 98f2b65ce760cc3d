"""Decide with one filter, map with another: `replay(..., association=HiddenIds(...,
map_noise=...))` (issue 16)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from ekfslam import pipeline, schedule
from ekfslam.core.association import AssociationConfig
from ekfslam.core.filter.associating import ASSOCIATED, AssociationCounts, AssociationLog
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter.mapping import MappingFilter
from ekfslam.core.noise import default_config, default_noise
from ekfslam.errors import ConfigError
from ekfslam.logs.runlog import read_run
from ekfslam.pipeline import replay
from ekfslam.strategies import HiddenIds

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"


def _same_state(a, b, tol: float = 1e-12) -> None:
    assert list(a.landmarks) == list(b.landmarks)
    assert a.mu.shape == b.mu.shape
    np.testing.assert_allclose(a.mu, b.mu, rtol=0, atol=tol)
    np.testing.assert_allclose(a.Sigma, b.Sigma, rtol=0, atol=tol)
    np.testing.assert_allclose(a.history.pose, b.history.pose, rtol=0, atol=tol)
    assert a.counts == b.counts


@pytest.mark.parametrize("method", ["nn", "jcbb", "mht"])
def test_mapping_with_the_deciding_noise_is_the_plain_hidden_replay(method: str):
    """Same noise, same order, same per-sighting Q (the time-stamp term too): the same filter."""
    run = read_run(RUNS / "square-2laps")
    config = AssociationConfig(method=method, time_sigma=0.2, hypotheses=2)
    plain = replay(run, association=config)
    mapped = replay(run, association=HiddenIds(config, map_noise=default_noise(run)))
    _same_state(mapped, plain)
    assert (mapped.association.estimated == plain.association.estimated).all()
    assert mapped.association.decision == plain.association.decision
    assert mapped.association.counts == plain.association.counts
    assert mapped.map_noise == default_noise(run) and plain.map_noise is None
    assert mapped.counts.accepted > 400  # the updates happened in the mapping filter


def test_mapping_with_a_wider_noise_changes_the_map_not_the_decisions():
    run = read_run(RUNS / "square-2laps")
    config = AssociationConfig(method="jcbb")
    noise = default_noise(run)
    wide = dataclasses.replace(noise, sigma_x=4 * noise.sigma_x, sigma_y=4 * noise.sigma_x)
    plain = replay(run, noise, association=config)
    mapped = replay(run, noise, association=HiddenIds(config, map_noise=wide))
    assert (mapped.association.estimated == plain.association.estimated).all()
    assert mapped.noise == noise and mapped.map_noise == wide
    assert np.abs(mapped.Sigma[:3, :3] - plain.Sigma[:3, :3]).max() > 1e-6


def test_the_barcodes_ids_as_decisions_are_the_known_replay():
    """Every sighting 'associated' with its true id: the mapping filter is the known-id replay."""
    run = read_run(RUNS / "octagon-2laps")
    noise, config = default_noise(run), default_config(run)
    ids = np.asarray(run.detections.tag_id, dtype=np.int64)
    counts = AssociationCounts(len(ids), 0, 0, 0, 0, 0, 0)
    log = AssociationLog("jcbb", ids, (ASSOCIATED,) * len(ids), counts)
    ekf = EKFSLAM(run.meta.nominal_start, None, config)
    mapper = MappingFilter(ekf, log, time_sigma=0.0)
    with np.errstate(all="ignore"):
        schedule.feed_hidden(mapper, pipeline.schedule(run, noise))
    assert mapper.finish() is log
    known = replay(run, noise, config)
    mapped = pipeline._result(run, ekf, 0.0, noise, config)
    _same_state(mapped, known)


def test_map_noise_is_a_noise_config():
    with pytest.raises(ConfigError, match="HiddenIds: map_noise must be"):
        HiddenIds(map_noise={"sigma_x": 0.005})


def test_decisions_of_another_schedule_are_refused():
    ids = np.array([0, 1, 2], dtype=np.int64)
    log = AssociationLog("nn", ids, (ASSOCIATED,) * 3, AssociationCounts(3, 0, 0, 0, 0, 0, 0))
    mapper = MappingFilter(EKFSLAM((0.0, 0.0, 0.0)), log)
    mapper.observe([[1.0, 0.0], [2.0, 0.5]], np.eye(2) * 0.01, 0.0)
    with pytest.raises(ValueError, match="3 decisions, 2 sightings fed"):
        mapper.finish()
    with pytest.raises(ValueError, match="3 decisions for more sightings"):
        mapper.observe([[1.0, 0.0], [2.0, 0.5]], np.eye(2) * 0.01, 1.0)


def test_keyframes_are_the_mapping_filters():
    run = read_run(RUNS / "square-2laps")
    config = AssociationConfig(method="jcbb")
    noise = default_noise(run)
    wide = dataclasses.replace(noise, sigma_x=4 * noise.sigma_x, sigma_y=4 * noise.sigma_x)
    mapped = replay(run, noise, association=HiddenIds(config, map_noise=wide), keyframes=3)
    last = mapped.keyframes.mu[-1][: len(mapped.mu)]
    np.testing.assert_array_equal(last, mapped.mu)
