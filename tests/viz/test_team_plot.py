"""The team's figures of notebook 13: the joint Σ's correlations named and split block by block,
and a joint state's ellipses, one per robot and landmark, every text at 11 pt."""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse

from ekfslam.core.filter.team import TeamEKF
from ekfslam.viz.team_plot import draw_team_state, plot_team_covariance, team_state_labels

matplotlib.use("Agg")


def _team() -> TeamEKF:
    team = TeamEKF()
    team.add_robot(2, [0.0, 0.0, 0.0], np.diag([0.01, 0.01, 0.01]))
    team.add_robot(5, [1.0, 0.5, 1.0], np.diag([0.04, 0.02, 0.01]))
    team.update(2, [1.0, 0.3], 7, np.diag([1e-3, 1e-3]))
    team.update(5, [0.8, -0.2], 4, np.diag([1e-3, 1e-3]))
    team.update_robot(2, 5, [1.1, 0.45], np.diag([1e-3, 1e-3]))
    return team


def test_the_labels_name_each_robot_then_each_landmark_in_row_order() -> None:
    assert team_state_labels({5: 3, 2: 0}, [7, 4]) == [
        *("x2", "y2", "θ2", "x5", "y5", "θ5"),
        *("m7x", "m7y", "m4x", "m4y"),
    ]


def test_the_correlation_image_is_split_after_each_pose_block() -> None:
    team = _team()
    fig = Figure(figsize=(8, 8))
    ax = fig.subplots()
    image = plot_team_covariance(ax, team.Sigma, team.rows, list(team.slot), title="Σ")
    C = image.get_array()
    assert C.shape == (10, 10) and np.allclose(np.diag(C), 1.0)
    assert np.all(np.abs(C) <= 1.0 + 1e-12)
    rows = [line.get_ydata() for line in ax.get_lines()]
    lines = sorted({round(y[0], 2) for y in rows if y[0] == y[1]})  # the horizontal ones
    assert lines == [2.5, 5.5]  # between the two pose blocks, and before the map
    assert [t.get_text() for t in ax.get_yticklabels()] == team_state_labels(
        team.rows, list(team.slot)
    )
    fig.canvas.draw()
    assert min(t.get_fontsize() for t in ax.get_xticklabels() + ax.get_yticklabels()) >= 11


def test_a_zero_variance_gives_zero_correlation() -> None:
    team = TeamEKF()
    team.add_robot(1, [0.0, 0.0, 0.0])  # a known start: Σ = 0
    ax = Figure().subplots()
    assert not np.any(plot_team_covariance(ax, team.Sigma, team.rows, []).get_array())


def test_the_state_is_drawn_as_one_ellipse_per_robot_and_landmark() -> None:
    team = _team()
    ax = Figure().subplots()
    draw_team_state(ax, team.mu, team.Sigma, team.rows, team.slot, "after", ls="--")
    ellipses = [p for p in ax.patches if isinstance(p, Ellipse)]
    assert len(ellipses) == 4
    assert ellipses[0].center == tuple(team.pose(2)[:2])
    labels = [e.get_label() for e in ellipses if e.get_label()]
    assert labels == ["robot 2, after", "robot 5, after", "landmarks, after"]
    assert all(e.get_linestyle() == "--" for e in ellipses)
