"""Figures: the seed's Figure 2 (map, ellipses, trajectory) and the helpers it is built from.

Every plot is drawn from a `ReplayResult` and its `History`; nothing here runs the filter.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.patches import Ellipse, Rectangle
from numpy.typing import ArrayLike, NDArray

from ekfslam.arena import Arena
from ekfslam.replay import ReplayResult
from ekfslam.runlog import RunLog

if TYPE_CHECKING:
    from ekfslam.teaching import UpdateSteps

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
    figsize: tuple[float, float] = (10.5, 7.5),
) -> Figure:
    """A standalone Figure 2 for one run (no pyplot state: safe in scripts and tests)."""
    fig = Figure(figsize=figsize, layout="constrained")
    ax = fig.add_subplot()
    true_start = None
    if run.groundtruth is not None and len(run.groundtruth.t):
        true_start = run.groundtruth.pose[0]
    plot_map(ax, run, result, arena_half_size=arena_half_size, true_start=true_start)
    ax.set_title(title or f"EKF SLAM: {run.meta.name}")
    # outside the axes: inside, it hid a landmark of the seed's runs
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=9)
    return fig


# --- helpers for the classroom notebooks --------------------------------------------------------


def draw_tags(ax: Axes, arena: Arena, *, label: str | None = "tags (AprilTags)") -> None:
    """The arena's tags as green squares with their ids and an arrow along each face's normal."""
    pos, normals = arena.tag_positions(), arena.tag_normals()
    ax.plot(pos[:, 0], pos[:, 1], "s", color="tab:green", ms=9, label=label)
    ax.quiver(
        pos[:, 0], pos[:, 1], normals[:, 0], normals[:, 1], color="tab:green",
        angles="xy", scale_units="xy", scale=8.0, width=0.005,
    )  # fmt: skip
    for tag in arena.tags:  # ids just outside the wall, clear of the normal arrows
        offset = -14 * np.asarray(tag.normal)
        ax.annotate(
            str(tag.id), tag.position, xytext=tuple(offset), textcoords="offset points",
            ha="center", va="center", color="darkgreen", fontweight="bold",
        )  # fmt: skip


def draw_pose_ellipses(
    ax: Axes,
    poses: ArrayLike,
    covariances: ArrayLike,
    *,
    every: int = 1,
    confidence: float = 0.95,
    label: str | None = None,
    **kwargs,
) -> None:
    """Position ellipses of poses (K, 3) with covariances (K, 3, 3), one every `every` poses."""
    poses = np.asarray(poses, dtype=float)
    covs = np.asarray(covariances, dtype=float)
    kwargs.setdefault("color", "tab:blue")
    for k in range(0, len(poses), max(1, every)):
        ax.add_patch(covariance_ellipse(poses[k, :2], covs[k, :2, :2], confidence, **kwargs))
    if label is not None:
        ax.plot([], [], "-", color=kwargs["color"], label=label)


def state_labels(landmark_ids: Sequence[int]) -> list[str]:
    """Names of the state entries of eq. (1): x, y, θ, then m{id}x, m{id}y per landmark slot."""
    names = ["x", "y", "θ"]
    for i in landmark_ids:
        names += [f"m{i}x", f"m{i}y"]
    return names


def plot_covariance_matrix(
    ax: Axes,
    Sigma: ArrayLike,
    landmark_ids: Sequence[int],
    *,
    correlation: bool = True,
    title: str | None = None,
) -> AxesImage:
    """Σ (or its correlation matrix) as a heat map, rows and columns named by `state_labels`.

    landmark_ids : the ids in slot order (see `ekfslam.teaching.landmark_slots`). Correlations
    are drawn on a fixed -1..1 scale so snapshots of a run can be compared; a variance of zero
    (a known start) gives a correlation of zero.
    """
    S = np.asarray(Sigma, dtype=float)
    if correlation:
        sd = np.sqrt(np.clip(np.diag(S), 0.0, None))
        scale = np.outer(sd, sd)
        S = np.divide(S, scale, out=np.zeros_like(S), where=scale > 0)
        image = ax.imshow(S, cmap="RdBu_r", vmin=-1.0, vmax=1.0)
    else:
        limit = float(np.abs(S).max()) or 1.0
        image = ax.imshow(S, cmap="RdBu_r", vmin=-limit, vmax=limit)
    names = state_labels(landmark_ids)[: len(S)]
    ax.set_xticks(range(len(S)), names, rotation=90, fontsize=7)
    ax.set_yticks(range(len(S)), names, fontsize=7)
    ax.set_xlabel("state entry (eq. 1)")
    ax.set_ylabel("state entry (eq. 1)")
    if title is not None:
        ax.set_title(title)
    return image


def update_figure(
    steps: UpdateSteps,
    landmark_ids: Sequence[int],
    *,
    truth: Mapping[int, ArrayLike] | None = None,
    figsize: tuple[float, float] = (12.0, 10.0),
) -> Figure:
    """One correction drawn step by step on four panels (eqs. 13-16).

    (a) the prior: robot and landmark ellipses; (b) the measurement z against the prediction ẑ,
    both drawn from the prior pose (eq. 12); (c) the correction K ν of every state entry;
    (d) the posterior (Joseph form) over the prior. `landmark_ids` are in slot order.
    """
    fig = Figure(figsize=figsize, layout="constrained")
    (a, b), (c, d) = fig.subplots(2, 2)
    mu0, mu1 = steps.mu_prior, steps.mu_post
    S0, S1 = steps.Sigma_prior, steps.Sigma_joseph
    j = steps.j
    lj = 3 + 2 * j

    def state(ax: Axes, mu, S, style: str, tag: str, alpha: float = 1.0) -> None:
        ax.add_patch(covariance_ellipse(mu[:2], S[:2, :2], color="tab:red", ls=style, alpha=alpha))
        ax.quiver(mu[0], mu[1], math.cos(mu[2]), math.sin(mu[2]), color="tab:red", alpha=alpha,
                  angles="xy", scale_units="xy", scale=8.0, width=0.006)  # fmt: skip
        for k in range(len(landmark_ids)):
            l = 3 + 2 * k
            color = "tab:blue" if k == j else "0.5"
            ax.add_patch(covariance_ellipse(mu[l : l + 2], S[l : l + 2, l : l + 2],
                                            color=color, ls=style, alpha=alpha))  # fmt: skip
        if alpha == 1.0 and style == "-":
            for k, i in enumerate(landmark_ids):
                ax.annotate(str(i), mu[3 + 2 * k : 5 + 2 * k], xytext=(8, 8),
                            textcoords="offset points", fontsize=9)  # fmt: skip
        ax.plot([], [], ls=style, color="tab:red", label=f"robot, {tag} (95%)")
        ax.plot([], [], ls=style, color="tab:blue", label=f"landmark {landmark_ids[j]}, {tag}")

    for ax in (a, b, d):
        if truth is not None:
            pts = np.array([truth[i] for i in landmark_ids])
            ax.plot(pts[:, 0], pts[:, 1], "o", color="tab:green", ms=5, label="true landmarks")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.grid(True, alpha=0.3)
    state(a, mu0, S0, "-", "prior")
    a.set_title("(a) prior: Σ after prediction (eq. 9)")
    state(b, mu0, S0, "-", "prior", alpha=0.35)
    r, phi = steps.z
    ang = mu0[2] + phi
    seen = mu0[:2] + r * np.array([math.cos(ang), math.sin(ang)])
    b.plot([mu0[0], seen[0]], [mu0[1], seen[1]], "-", color="tab:orange", lw=2,
           label=f"measured z: r = {r:.3f} m, φ = {phi:.3f} rad")  # fmt: skip
    b.plot(*seen, "x", color="tab:orange", ms=12, mew=3)
    b.plot([mu0[0], mu0[lj]], [mu0[1], mu0[lj + 1]], "--", color="tab:blue",
           label=f"predicted ẑ (eq. 13): r = {steps.z_hat[0]:.3f} m, "
                 f"φ = {steps.z_hat[1]:.3f} rad")  # fmt: skip
    b.set_title(
        f"(b) measurement vs prediction: ν = ({steps.nu[0]:+.3f} m, {steps.nu[1]:+.3f} rad)"
    )
    correction = steps.K @ steps.nu
    names = state_labels(landmark_ids)
    colors = ["tab:red"] * 3 + ["tab:blue" if k // 2 == j else "0.6" for k in range(len(names) - 3)]
    c.bar(range(len(names)), correction * 1000.0, color=colors, label="K ν (mm, mrad for θ)")
    c.set_xticks(range(len(names)), names, rotation=90)
    c.axhline(0.0, color="k", lw=0.8)
    c.set_xlabel("state entry (eq. 1)")
    c.set_ylabel("correction K ν (mm or mrad)")
    c.set_title("(c) gain times innovation (eqs. 15-16): every correlated entry moves")
    state(d, mu0, S0, ":", "prior", alpha=0.6)
    state(d, mu1, S1, "-", "posterior")
    d.set_title("(d) posterior (eq. 16, Joseph form): ellipses shrink")
    for ax in (a, b, c, d):
        ax.legend(loc="best", fontsize=8, framealpha=0.85)
    return fig
