"""Tests of the notebook helpers in ekfslam.viz.plotting (Figure 2 itself is tested elsewhere)."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse

from ekfslam.core.arena import SEED_ARENA
from ekfslam.core.steps import update_steps
from ekfslam.viz.plotting import (
    draw_pose_ellipses,
    draw_tags,
    ellipse_parameters,
    plot_covariance_matrix,
    state_labels,
    update_figure,
)
from ekfslam.viz.style import TRUTH


def _axes():
    return Figure().add_subplot()


def test_state_labels_follow_eq_1() -> None:
    assert state_labels([4, 1]) == ["x", "y", "θ", "m4x", "m4y", "m1x", "m1y"]
    assert state_labels([]) == ["x", "y", "θ"]


def test_draw_tags_labels_every_tag_outside_the_walls() -> None:
    ax = _axes()
    draw_tags(ax, SEED_ARENA)
    texts = {int(t.get_text()): t for t in ax.texts}
    assert sorted(texts) == list(range(8))
    for tag in SEED_ARENA.tags:
        offset = np.asarray(texts[tag.id].xyann)  # in points, away from the tag
        # the label sits against the normal: behind the wall, clear of the arrow
        assert float(offset @ tag.normal) < 0
    (points,) = ax.lines
    np.testing.assert_array_equal(np.column_stack(points.get_data()), SEED_ARENA.tag_positions())


def test_draw_pose_ellipses_draws_every_nth_with_the_right_size() -> None:
    ax = _axes()
    poses = np.column_stack([np.arange(5.0), np.zeros(5), np.zeros(5)])
    covs = np.array([np.diag([0.01 * (k + 1), 0.04, 1.0]) for k in range(5)])
    draw_pose_ellipses(ax, poses, covs, every=2, label="ellipses")
    ellipses = [p for p in ax.patches if isinstance(p, Ellipse)]
    assert [e.center for e in ellipses] == [(0.0, 0.0), (2.0, 0.0), (4.0, 0.0)]
    for e, k in zip(ellipses, (0, 2, 4), strict=True):
        width, height, _ = ellipse_parameters(covs[k, :2, :2])
        assert sorted([e.width, e.height]) == pytest.approx(sorted([width, height]))
    assert [line.get_label() for line in ax.lines] == ["ellipses"]


def test_plot_covariance_matrix_shows_correlations() -> None:
    Sigma = np.array(
        [
            [0.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, 4.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0, 0.0, -0.5],
            [0.0, 1.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, -0.5, 0.0, 1.0],
        ]
    )
    ax = _axes()
    image = plot_covariance_matrix(ax, Sigma, [7], title="t = 0")
    data = image.get_array()
    assert data[0, 0] == 0.0  # a zero variance (known start) gives no correlation, not NaN
    assert data[1, 3] == pytest.approx(1.0 / (2.0 * 1.0))
    assert data[2, 4] == pytest.approx(-0.5)
    np.testing.assert_allclose(np.diag(data)[1:], 1.0)
    assert image.get_clim() == (-1.0, 1.0)
    assert [t.get_text() for t in ax.get_xticklabels()] == ["x", "y", "θ", "m7x", "m7y"]
    assert ax.get_title() == "t = 0"
    raw = plot_covariance_matrix(_axes(), Sigma, [7], correlation=False)
    assert raw.get_clim() == (-4.0, 4.0)
    np.testing.assert_array_equal(raw.get_array(), Sigma)


def test_update_figure_has_four_panels_and_the_corrections() -> None:
    mu = np.array([0.0, 0.0, 0.2, 1.0, 0.5, -0.5, 1.0])
    Sigma = np.diag([1e-3, 1e-3, 1e-3, 4e-3, 4e-3, 9e-3, 9e-3])
    Sigma[0, 3] = Sigma[3, 0] = 5e-4
    steps = update_steps(mu, Sigma, 0, [1.15, 0.25], np.diag([1e-3, 1e-3]))
    truth = {2: [1.0, 0.55], 5: [-0.5, 1.0]}
    fig = update_figure(steps, [2, 5], truth=truth)
    assert len(fig.axes) == 4
    bars = fig.axes[2].patches
    np.testing.assert_allclose([b.get_height() for b in bars], 1000 * steps.K @ steps.nu)
    assert [t.get_text() for t in fig.axes[2].get_xticklabels()] == state_labels([2, 5])
    # the posterior panel draws prior and posterior: twice the ellipses of the prior panel
    count = [sum(isinstance(p, Ellipse) for p in ax.patches) for ax in fig.axes]
    assert count[0] == 3 and count[3] == 6
    fig.canvas.draw()  # renders without error


def test_update_figure_keeps_the_map_legends_off_the_maps() -> None:
    """Regression: panel (b)'s legend, placed "best" inside, covered an ellipse in notebook 05."""
    mu = np.array([0.0, 0.0, 0.2, 1.0, 0.5, -0.5, 1.0])
    Sigma = np.diag([1e-3, 1e-3, 1e-3, 4e-3, 4e-3, 9e-3, 9e-3])
    steps = update_steps(mu, Sigma, 0, [1.15, 0.25], np.diag([1e-3, 1e-3]))
    fig = update_figure(steps, [2, 5], truth={2: [1.0, 0.55], 5: [-0.5, 1.0]})
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    for k in (0, 1, 3):  # (a), (b), (d): the maps
        ax = fig.axes[k]
        legend = ax.get_legend().get_window_extent(renderer)
        assert not legend.overlaps(ax.get_window_extent(renderer)), ax.get_title()
        page = fig.bbox.padded(1.0)  # constrained layout sets the lowest one flush on the edge
        assert page.contains(legend.x0, legend.y0) and page.contains(legend.x1, legend.y1)


def test_figure2_says_before_alignment_and_draws_the_aligned_map_beside_it() -> None:
    """Regression: the unaligned map over the true tags, unlabelled, next to a 0.005 m error."""
    from pathlib import Path

    from matplotlib.text import Text

    from ekfslam import read_run
    from ekfslam.analysis.alignment import align
    from ekfslam.core.noise import default_config, default_noise
    from ekfslam.pipeline import replay
    from ekfslam.viz.plotting import figure2

    run = read_run(Path(__file__).resolve().parents[2] / "data" / "runs" / "octagon-2laps")
    result = replay(run, default_noise(run), default_config(run))
    a = align(result.landmarks, run.meta.tag_map)
    fig = figure2(run, result, arena_half_size=0.75, alignment=a)
    before, after = fig.axes
    assert before.get_title().startswith("before alignment")
    assert after.get_title().startswith("after the eq. (17) alignment")
    assert f"mean error {a.mean_error:.3f} m over 8 landmarks" in after.get_title()
    # the right panel's red circles are the aligned estimate, where the error is measured
    (circles,) = [line for line in after.lines if line.get_label() == "estimated landmarks"]
    np.testing.assert_allclose(np.column_stack(circles.get_data()), a.aligned, atol=1e-12)
    (raw,) = [line for line in before.lines if line.get_label() == "estimated landmarks"]
    ids = sorted(result.landmarks)
    np.testing.assert_allclose(
        np.column_stack(raw.get_data()), [result.landmarks[i] for i in ids], atol=1e-12
    )
    # the true tags carry their ids on both panels
    for ax in (before, after):
        green = {t.get_text() for t in ax.texts if t.get_color() == TRUTH}
        assert green == {str(i) for i in range(8)}
    (legend,) = fig.legends
    assert min(t.get_fontsize() for t in legend.get_texts()) >= 11
    assert "true landmarks (id)" in [t.get_text() for t in legend.get_texts()]
    assert isinstance(fig.texts[0], Text)  # the suptitle names the run
    assert fig.texts[0].get_text() == "EKF SLAM: octagon-2laps"
