"""The stress scenario (issue 16): close pairs of tags and a drifting loop, nn against jcbb."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.collections import LineCollection

from ekfslam.analysis.association_stress import stress_study
from ekfslam.sim.scenarios import pairs_arena, scenario
from ekfslam.sim.simulation import simulate
from ekfslam.viz.association import plot_wrong_associations

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def study():
    return stress_study(runs=1, first_seed=2)  # the README's seed: about 2 s


def test_the_stress_world_is_close_pairs_seen_together():
    arena = pairs_arena()
    xy = arena.tag_positions()
    assert xy.shape == (16, 2)
    np.testing.assert_allclose(np.hypot(*(xy[0::2] - xy[1::2]).T), 0.3, rtol=1e-3)
    config, arena = scenario("stress", seed=2)
    assert config.laps == 2 and config.wheel_noise_sigma == 1.0
    run = simulate(config, arena)
    det = run.detections
    assert set(det.tag_id.tolist()) == set(range(16))
    # both tags of a pair in one frame: the joint test has something to work with
    both = sum(
        {2 * k, 2 * k + 1} <= set(det.tag_id[det.t == t].tolist())
        for t in np.unique(det.t)
        for k in range(8)
    )
    assert both > 100


def test_nn_fails_and_jcbb_survives_on_seed_2(study):
    known, nn, joint = (study.cases[m][0] for m in ("known", "nn", "jcbb"))
    assert nn.correct_fraction < 0.85 and nn.wrong > 100
    assert joint.correct_fraction > 0.97 and joint.wrong <= 5
    assert nn.aligned_error > 3.0 * known.aligned_error
    assert joint.aligned_error < 1.5 * known.aligned_error
    # the picture's segments are the wrong sightings, each from the robot to a true tag
    assert len(study.wrong["nn"]) == nn.wrong and len(study.wrong["jcbb"]) == joint.wrong
    tags = np.array(list(study.tags.values()))
    ends = study.wrong["nn"][:, 1]
    assert np.min(np.hypot(*(ends[:, None] - tags[None]).transpose(2, 0, 1)), axis=1).max() < 1e-9
    d = study.as_dict()
    assert d["nn"]["correct_fraction"] == nn.correct_fraction and d["seeds"] == [2]


def test_the_figure_draws_one_line_per_wrong_association(study):
    fig = plot_wrong_associations(study)
    left, right = fig.axes
    (lines,) = [c for c in left.collections if isinstance(c, LineCollection)]
    assert len(lines.get_segments()) == study.cases["nn"][0].wrong
    assert "nn" in left.get_title() and "jcbb" in right.get_title()


def test_runs_must_be_positive():
    with pytest.raises(ValueError, match="runs"):
        stress_study(runs=0)
