"""MRCLAM with the barcodes hidden, by filter: known's column is the shipped default for all."""

from __future__ import annotations

from pathlib import Path

import pytest

from ekfslam.analysis.association_mrclam import association_robots, association_table


def test_the_invariant_filter_associates_but_known_stays_the_shipped_standard(mrclam7: Path):
    """2026-12-01, Dataset 7 robot 2, jcbb: 0.040 m standard, 0.054 m invariant, against 0.027 m
    known; the invariant EKF is consistent here, yet it does not associate better."""
    standard, invariant = (
        association_robots(mrclam7, ("jcbb",), robots=(2,), linearization=lin)[0]
        for lin in ("standard", "invariant")
    )
    assert (standard.linearization, invariant.linearization) == ("standard", "invariant")
    assert invariant.known_error == standard.known_error == pytest.approx(0.027, abs=0.003)
    assert invariant.known_same_noise != standard.known_same_noise  # replayed by the other filter
    assert standard.aligned_error == pytest.approx(0.040, abs=0.005)
    assert invariant.aligned_error == pytest.approx(0.054, abs=0.005)
    assert invariant.ratio == pytest.approx(invariant.aligned_error / invariant.known_error)
    assert "invariant EKF (known: standard)" in association_table([invariant])
