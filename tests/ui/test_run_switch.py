"""The panel when the student picks another run: R and Q follow runs with other documented
noise, the NIS axis counts from the run's start, and the legends stay off the data.

Built from the seed's square: a copy whose documented noise is a MRCLAM robot's (σr 0.3 m) and
whose clock is Unix time, as a MRCLAM log's is; no shared data needed.
"""

from __future__ import annotations

from dataclasses import replace

import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ekfslam.core.noise import NoiseConfig
from ekfslam.logs.mrclam.defaults import MRCLAM_NOISE
from ekfslam.logs.runlog import read_run
from ekfslam.places import seed_runs_dir
from ekfslam.ui.tuning import DEFAULT_FIGSIZE, Tuner, seed_runs
from ekfslam.ui.widgets import tuning_panel

EPOCH = 1.248e9  # s, about when MRCLAM was recorded


def shifted(run, dt: float):
    """`run` with every time stamp moved by dt seconds."""
    moved = {}
    for name in ("controls", "detections", "groundtruth"):
        part = getattr(run, name)
        if part is not None:
            moved[name] = replace(part, t=part.t + dt)
    return replace(run, **moved)


@pytest.fixture(scope="module")
def runs():
    square = read_run(seed_runs_dir() / "square-2laps")
    robot = shifted(replace(square, meta=replace(square.meta, defaults="mrclam")), EPOCH)
    return {**seed_runs(), "robot": lambda: robot}


def test_a_run_with_other_documented_noise_brings_its_own(runs) -> None:
    tuner = Tuner(runs, Figure())
    assert tuner.settings.noise == NoiseConfig()  # the seed's square's defaults
    tuned = tuner.apply(sigma_range=0.05).settings.noise
    # Before this, the σr of 5 cm went with the student to the robot tuned for 0.3 m.
    assert tuner.apply(run="robot").settings.noise == MRCLAM_NOISE
    tuner.apply(sigma_bearing=0.02)
    robot_tuned = tuner.settings.noise
    # back on a seed run the student's own seed tuning returns, and the robot's is kept
    assert tuner.apply(run="octagon-2laps").settings.noise == tuned
    assert tuner.apply(run="robot").settings.noise == robot_tuned


def test_runs_with_the_same_defaults_keep_the_setting(runs) -> None:
    tuner = Tuner(runs, Figure())
    tuned = tuner.apply(sigma_theta=0.04).settings.noise
    assert tuner.apply(run="octagon-2laps").settings.noise == tuned  # compare at one setting


def test_noise_named_with_the_run_wins(runs) -> None:
    tuner = Tuner(runs, Figure())
    noise = tuner.apply(run="robot", sigma_range=0.2).settings.noise
    assert noise == replace(MRCLAM_NOISE, sigma_range=0.2)


def test_the_nis_axis_counts_from_the_run_start(runs) -> None:
    tuner = Tuner(runs, Figure())
    tuner.apply(run="robot")
    t = tuner.view.accepted.get_xdata()
    lo, hi = tuner.view.nis_ax.get_xlim()
    # Before this, the axis ran from 1.248e9 s with an offset label over it.
    assert lo == 0.0 and 0.0 <= t.min() < 5.0 and hi == pytest.approx(t.max(), abs=2.0)
    assert hi < 200.0


def test_the_legends_cover_no_data(runs) -> None:
    tuner = Tuner(runs, Figure(figsize=DEFAULT_FIGSIZE))
    tuner.apply(run="robot")
    fig = tuner.figure
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    for ax in (tuner.view.map_ax, tuner.view.nis_ax):
        legend = ax.get_legend().get_window_extent(renderer)
        assert not legend.overlaps(ax.get_window_extent(renderer)), ax.get_title()
        assert fig.bbox.contains(legend.x0, legend.y0) and fig.bbox.contains(legend.x1, legend.y1)


def test_the_sliders_follow_the_run_picked_in_the_panel(runs) -> None:
    panel = tuning_panel(runs, figure=Figure())
    panel.run.value = "robot"  # what the dropdown does: the observer, then the scheduled replay
    shown = {name: slider.value for name, slider in panel.sliders.items()}
    assert shown == pytest.approx({n: getattr(MRCLAM_NOISE, n) for n in shown}, rel=1e-12)
    assert panel.tuner.settings.noise == MRCLAM_NOISE
