"""MRCLAM with the barcodes hidden, by filter: known's column is the shipped default for all."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from studies.association_mrclam import association_robots, association_table


def test_the_invariant_filter_associates_but_known_stays_the_shipped_standard(mrclam7: Path):
    """2026-12-02, Dataset 7 robot 2, jcbb, its own map, a time-stamp error per sighting and
    founding by the likelihood ratio: 0.061 m standard, 0.065 m invariant, against 0.027 m known
    (with the NIS-23 founding 0.040 and 0.054 m); the invariant EKF is consistent here, yet it
    does not associate better."""
    standard, invariant = (
        association_robots(
            mrclam7, ("jcbb",), robots=(2,), linearization=lin, mapped=False, time_shared=False
        )[0]
        for lin in ("standard", "invariant")
    )
    assert (standard.linearization, invariant.linearization) == ("standard", "invariant")
    assert invariant.known_error == standard.known_error == pytest.approx(0.027, abs=0.003)
    assert invariant.known_same_noise != standard.known_same_noise  # replayed by the other filter
    assert standard.aligned_error == pytest.approx(0.061, abs=0.005)
    assert invariant.aligned_error == pytest.approx(0.065, abs=0.005)
    assert invariant.ratio == pytest.approx(invariant.aligned_error / invariant.known_error)
    assert "invariant EKF (known: standard)" in association_table([invariant])


def _dataset(number: int, data_missing) -> Path:
    from ekfslam.errors import InputError
    from ekfslam.logs.mrclam.load import find_dataset

    try:
        return find_dataset(number)
    except InputError:
        data_missing(
            f"MRCLAM Dataset {number} is not here: `python -m ekfslam fetch mrclam {number}`"
        )


@pytest.mark.slow
@pytest.mark.parametrize(
    ("dataset", "robot", "jcbb", "mht"), [(4, 1, 17.5, 1.05), (1, 2, 73.8, 0.94)]
)
def test_the_bank_keeps_the_robots_jcbb_loses(dataset, robot, jcbb, mht, data_missing):
    """2026-12-02, `score-mrclam 4|1 --association jcbb mht --map-noise none --time-error
    independent`: an early wrong pairing sends JCBB to 17-74x known's map error (with the NIS-23
    founding 42x and 36x); the bank of 8 hypotheses maps these robots as well as known."""
    rows = association_robots(
        _dataset(dataset, data_missing),
        ("jcbb", "mht"),
        robots=(robot,),
        mapped=False,
        time_shared=False,
    )
    assert [r.method for r in rows] == ["jcbb", "mht"]
    assert rows[0].ratio == pytest.approx(jcbb, rel=0.1)
    assert rows[1].ratio == pytest.approx(mht, abs=0.15)
    assert rows[1].correct_fraction > 0.98 > 0.9 > rows[0].correct_fraction


@pytest.mark.slow
def test_dataset_7_with_the_bank(mrclam7: Path):
    """2026-12-02, its own map, a time-stamp error per sighting, mht founding by the threshold
    (its default): mht 0.163 / 0.104 m on robots 1 and 5 (2.70x, 2.49x), against jcbb's 1.66x,
    2.40x: on Dataset 7's clusters the bank decides more sightings right (80.7%, 79.0%) and its
    own map does not reach 1.5x known (founding by the likelihood ratio: robot 5 2.29x)."""
    rows = association_robots(mrclam7, ("mht",), robots=(1, 5), mapped=False, time_shared=False)
    assert [round(r.ratio, 1) for r in rows] == pytest.approx([2.7, 2.5], abs=0.25)
    assert [r.correct_fraction for r in rows] == pytest.approx([0.807, 0.790], abs=0.02)


def test_the_mapping_noise_is_the_consistency_noise_with_the_maps_translation():
    """MRCLAM maps with sigma_x = sigma_y = 0.005 (MRCLAM_NOISE's) and the rest of the noise
    that decides; the seed's runs have no mapping filter (their ideal noise decides and maps)."""
    from ekfslam.analysis.association import association_map_noise
    from ekfslam.logs.mrclam import defaults
    from ekfslam.logs.runlog import read_run

    noise = defaults.MRCLAM_MAP_NOISE
    assert noise == dataclasses.replace(
        defaults.MRCLAM_CONSISTENT_NOISE, sigma_x=0.005, sigma_y=0.005
    )
    assert (noise.sigma_x, noise.sigma_y) == (defaults.MRCLAM_NOISE.sigma_x, 0.005)
    seed = read_run(Path(__file__).resolve().parents[2] / "data" / "runs" / "square-2laps")
    assert association_map_noise(seed) is None
    mrclam = dataclasses.replace(seed, meta=dataclasses.replace(seed.meta, defaults="mrclam"))
    assert association_map_noise(mrclam) is noise


#: `score-mrclam 7 --association jcbb mht [--time-error independent] [--new-rule threshold]`
#: (2026-12-02): mht's and jcbb's ratios to known, their means, and mht's correct shares, by
#: time-stamp error and founding rule. The first is the shipped default (founding: jcbb by the
#: likelihood ratio, mht by the threshold, `AssociationConfig.new_rule`).
DATASET_7_MAPPED = {
    ("shared", None): (
        [0.98, 1.31, 0.99, 1.30, 1.26],
        1.17,
        [1.22, 1.45, 1.34, 1.29, 1.28],
        1.32,
        [0.790, 0.857, 0.860, 0.827, 0.800],
    ),
    ("shared", "threshold"): (
        [0.98, 1.31, 0.99, 1.30, 1.26],
        1.17,
        [1.18, 1.60, 1.23, 1.29, 1.57],
        1.37,
        [0.79, 0.86, 0.86, 0.83, 0.80],
    ),
    ("independent", "threshold"): (
        [1.84, 1.51, 0.99, 1.32, 1.34],
        1.40,
        [1.17, 1.64, 1.47, 1.30, 1.65],
        1.45,
        [0.807, 0.846, 0.826, 0.824, 0.790],
    ),
}


@pytest.mark.slow
@pytest.mark.parametrize(("time_error", "new_rule"), list(DATASET_7_MAPPED))
def test_dataset_7_mapped_by_a_second_filter(mrclam7: Path, time_error, new_rule):
    """2026-12-01, `score-mrclam 7 --association jcbb mht`: deciding under the consistency noise
    and mapping with sigma_x = sigma_y = 0.005 takes mht from 2.70/2.20/2.03/1.34/2.49x known to
    1.84/1.51/0.99/1.32/1.34x (mean 2.15x -> 1.40x) and jcbb from a mean of 1.80x to 1.45x; the
    decisions are the same ones (the correct shares do not move). 2026-12-02: one time-stamp
    error per image takes mht within 1.5x on every robot (worst 1.31x) and jcbb to 1.60x at
    worst; with jcbb founding by the likelihood ratio too (the default) jcbb is within 1.5x on
    every robot (worst 1.45x, robot 2), and so is mht (worst 1.31x; founding by the likelihood
    ratio it would be 1.61x, robot 1)."""
    rows = association_robots(
        mrclam7, ("jcbb", "mht"), time_shared=time_error == "shared", new_rule=new_rule
    )
    mht_ratios, mht_mean, jcbb_ratios, jcbb_mean, mht_correct = DATASET_7_MAPPED[
        time_error, new_rule
    ]
    assert all(r.mapped for r in rows)
    jcbb = [r.ratio for r in rows if r.method == "jcbb"]
    mht = [r for r in rows if r.method == "mht"]
    assert [r.ratio for r in mht] == pytest.approx(mht_ratios, abs=0.1)
    assert np.mean([r.ratio for r in mht]) == pytest.approx(mht_mean, abs=0.05)
    assert jcbb == pytest.approx(jcbb_ratios, abs=0.1)
    assert np.mean(jcbb) == pytest.approx(jcbb_mean, abs=0.05)
    assert [r.correct_fraction for r in mht] == pytest.approx(mht_correct, abs=0.01)
    if new_rule is None:  # the default meets 1.5x of known on every robot, both methods
        assert max(jcbb) < 1.5 and max(r.ratio for r in mht) < 1.5


@pytest.mark.slow
def test_dataset_4_mapped_by_a_second_filter(data_missing):
    """2026-12-01, `score-mrclam 4 --association jcbb mht`: the bank's decisions mapped with
    sigma_x = sigma_y = 0.005, robots 1 and 2 at 1.22x and 2.06x known (its own map: robot 1
    1.05x; the five robots' worst / mean 2.18 / 1.58x -> 2.06 / 1.20x). 2026-12-02, one
    time-stamp error per image: 1.22x and 2.05x (mean 1.19x)."""
    rows = association_robots(_dataset(4, data_missing), ("mht",), robots=(1, 2))
    assert [r.ratio for r in rows] == pytest.approx([1.22, 2.06], abs=0.15)
    assert [r.correct_fraction for r in rows] == pytest.approx([0.999, 0.982], abs=0.01)
