"""Figures: the seed's Figure 2 (map, ellipses, trajectory) and the helpers it is built from.

Every plot is drawn from a `ReplayResult` and its `History`; nothing here runs the filter.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse, Rectangle
from numpy.typing import ArrayLike, NDArray

from ekfslam.replay import ReplayResult
from ekfslam.runlog import RunLog

#: chi-square(2 dof) quantiles: the Mahalanobis radius² of a 2-D confidence ellipse.
CHI2_2DOF = {0.39: 1.0, 0.95: 5.991464547107979, 0.99: 9.21034037197618}


def ellipse_parameters(cov: ArrayLike, confidence: float = 0.95) -> tuple[float, float, float]:
    """Width, height (m, full axes) and angle (degrees) of a 2-D covariance's confidence ellipse."""
    cov = np.asarray(cov, dtype=float)
    k2 = CHI2_2DOF.get(confidence, -2.0 * math.log(1.0 - confidence))
    vals, vecs = np.linalg.eigh(0.5 * (cov + cov.T))
    vals = np.clip(vals, 0.0, None)
    width, height = 2.0 * np.sqrt(k2 * vals[::-1])
    angle = math.degrees(math.atan2(vecs[1, 1], vecs[0, 1]))
    return float(width), float(height), angle


def covariance_ellipse(
    mean: ArrayLike, cov: ArrayLike, confidence: float = 0.95, **kwargs
) -> Ellipse:
    """A matplotlib Ellipse patch for `confidence` (default 95%) of N(mean, cov)."""
    width, height, angle = ellipse_parameters(cov, confidence)
    kwargs.setdefault("fill", False)
    return Ellipse(tuple(np.asarray(mean, dtype=float)), width, height, angle=angle, **kwargs)


def draw_arena(ax: Axes, half_size: float) -> None:
    """The arena's walls as a square centred at the origin."""
    ax.add_patch(
        Rectangle(
            (-half_size, -half_size), 2 * half_size, 2 * half_size,
            fill=False, lw=2, color="0.3", label="arena walls",
        )
    )  # fmt: skip


def draw_trajectory(ax: Axes, poses: NDArray, arrows: int = 60, **kwargs) -> None:
    """The path as a line with about `arrows` heading arrows along it."""
    poses = np.asarray(poses, dtype=float)
    ax.plot(poses[:, 0], poses[:, 1], "-", color=kwargs.get("color", "tab:red"), lw=1, alpha=0.6)
    step = max(1, len(poses) // arrows)
    p = poses[::step]
    ax.quiver(
        p[:, 0], p[:, 1], np.cos(p[:, 2]), np.sin(p[:, 2]),
        color=kwargs.get("color", "tab:red"), angles="xy", scale_units="xy",
        scale=kwargs.get("arrow_scale", 12.0), width=0.004, label=kwargs.get("label"),
    )  # fmt: skip


def plot_map(
    ax: Axes,
    run: RunLog,
    result: ReplayResult,
    *,
    arena_half_size: float | None = None,
    true_start: ArrayLike | None = None,
    confidence: float = 0.95,
) -> None:
    """The seed's Figure 2 on one axes.

    Red arrows: the estimated trajectory; red hollow circles: estimated landmarks (before
    alignment) with blue `confidence` ellipses; green dots: true landmarks; blue dot: the true
    start (when known).
    """
    if arena_half_size is not None:
        draw_arena(ax, arena_half_size)
    h = result.history
    if len(h.pose):
        draw_trajectory(ax, h.pose, label="estimated trajectory")
    if run.meta.tag_map:
        truth = np.array([run.meta.tag_map[i] for i in sorted(run.meta.tag_map)])
        ax.plot(truth[:, 0], truth[:, 1], "o", color="tab:green", ms=8, label="true landmarks")
    if result.landmarks:
        ids = sorted(result.landmarks)
        est = np.array([result.landmarks[i] for i in ids])
        ax.plot(
            est[:, 0], est[:, 1], "o", mfc="none", mec="tab:red", ms=10, mew=1.5,
            label="estimated landmarks",
        )  # fmt: skip
        for i in ids:
            ax.add_patch(
                covariance_ellipse(
                    result.landmarks[i], result.landmark_covariances[i], confidence,
                    color="tab:blue", lw=1.2,
                )
            )  # fmt: skip
            ax.annotate(str(i), result.landmarks[i], xytext=(6, 6), textcoords="offset points")
        ax.plot([], [], "-", color="tab:blue", label=f"{confidence:.0%} covariance ellipses")
    if true_start is not None:
        s = np.asarray(true_start, dtype=float)
        ax.plot(s[0], s[1], "o", color="tab:blue", ms=9, label="true start")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, alpha=0.3)


def figure2(
    run: RunLog,
    result: ReplayResult,
    *,
    arena_half_size: float | None = None,
    title: str | None = None,
    figsize: tuple[float, float] = (8.0, 8.0),
) -> Figure:
    """A standalone Figure 2 for one run (no pyplot state: safe in scripts and tests)."""
    fig = Figure(figsize=figsize, layout="constrained")
    ax = fig.add_subplot()
    true_start = None
    if run.groundtruth is not None and len(run.groundtruth.t):
        true_start = run.groundtruth.pose[0]
    plot_map(ax, run, result, arena_half_size=arena_half_size, true_start=true_start)
    ax.set_title(title or f"EKF SLAM: {run.meta.name}")
    ax.legend(loc="upper right", fontsize=8, framealpha=0.85)
    return fig
