"""The association section of ``bench``: what it measures and how the table shows it."""

from __future__ import annotations

from benchmarks.association import SIGHTINGS, association_lines, bench_association
from ekfslam.places import seed_runs_dir


def test_association_bench_measures_every_method_and_every_m():
    r = bench_association(seed_runs_dir(), repeats=1)
    per = r["association_replay_us_per_sighting"]
    assert all(per[m] > 0 for m in ("known", "nn", "jcbb", "mht"))
    assert set(r["association_step_ms"]) == {str(m) for m in SIGHTINGS}
    for step in r["association_step_ms"].values():
        assert step["nn"] > 0 and step["jcbb"] > 0 and step["jcbb_numpy"] > 0
        assert step["jcbb_nodes"] >= 1
        assert step["jcbb_correct"] and not step["budget_hit"]  # a clean scene: no excuse
    table = "\n".join(association_lines(r))
    assert "| association, octagon replay | known | nn | jcbb | mht |" in table
    assert "| jcbb, numpy form (ms) |" in table
    assert association_lines({}) == []  # an older bench.json has no association section


def test_without_the_seed_runs_the_replay_figures_are_none():
    r = bench_association(None, repeats=1)
    assert r["association_replay_us_per_sighting"] == dict.fromkeys(("known", "nn", "jcbb", "mht"))
    assert "– |" in "\n".join(association_lines(r))
