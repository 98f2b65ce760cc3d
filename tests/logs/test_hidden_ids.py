"""A source's replay with hidden ids: by its defaults name, the analysis naming no source."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from ekfslam.analysis.association import (
    association_config,
    association_map_noise,
    association_noise,
)
from ekfslam.logs.hidden_ids import hidden_id_defaults
from ekfslam.logs.mrclam import defaults
from ekfslam.logs.runlog import read_run

SEED = Path(__file__).resolve().parents[2] / "data" / "runs" / "square-2laps"


def test_mrclam_decides_wide_maps_tight_and_its_time_stamps_are_off():
    seed = read_run(SEED)
    mrclam = dataclasses.replace(seed, meta=dataclasses.replace(seed.meta, defaults="mrclam"))
    d = hidden_id_defaults(mrclam.meta)
    assert d is not None
    assert (d.noise, d.map_noise) == (defaults.MRCLAM_CONSISTENT_NOISE, defaults.MRCLAM_MAP_NOISE)
    assert (d.time_sigma, d.time_shared) == (0.2, True)
    assert association_noise(mrclam) == defaults.MRCLAM_CONSISTENT_NOISE
    assert association_map_noise(mrclam) == defaults.MRCLAM_MAP_NOISE
    c = association_config(mrclam, "jcbb")
    assert (c.time_sigma, c.time_shared) == (0.2, True)
    assert association_config(mrclam, "jcbb", time_shared=False).time_shared is False


def test_a_source_not_listed_replays_with_its_own_noise_and_exact_time_stamps():
    seed = read_run(SEED)
    assert hidden_id_defaults(seed.meta) is None
    realistic = dataclasses.replace(seed.meta, defaults="realistic")  # tuned, but not for this
    assert hidden_id_defaults(realistic) is None
    assert association_map_noise(seed) is None
    c = association_config(seed, "mht")
    assert (c.time_sigma, c.time_shared) == (0.0, False)
