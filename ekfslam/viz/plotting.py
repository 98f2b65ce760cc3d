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

from ekfslam.core.arena import Arena
from ekfslam.core.filter.config import chi2_2dof_quantile
from ekfslam.geometry import rotation, wrap_angle
from ekfslam.logs.runlog import RunLog
from ekfslam.viz.style import ESTIMATE, FONT, MEASUREMENT, START, TRUTH, UNCERTAINTY

if TYPE_CHECKING:
    from ekfslam.analysis.alignment import Alignment
    from ekfslam.core.steps import UpdateSteps
    from ekfslam.pipeline import ReplayResult

#: The Mahalanobis radius² of a 2-D confidence ellipse is the chi-square(2 dof) quantile
#: -2 ln(1 - p) (`chi2_2dof_quantile`); "39%" names the 1-sigma ellipse, radius² 1 (p = 1 - e^-½).
CHI2_2DOF = {0.39: 1.0}


def ellipse_parameters(cov: ArrayLike, confidence: float = 0.95) -> tuple[float, float, float]:
    """Width, height (m, full axes) and angle (degrees) of a 2-D covariance's confidence ellipse."""
    cov = np.asarray(cov, dtype=float)
    k2 = CHI2_2DOF.get(confidence) or chi2_2dof_quantile(confidence)
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
            (-half_size, -half_size),
            2 * half_size,
            2 * half_size,
            fill=False,
            lw=2,
            color="0.3",
            label="arena walls",
        )
    )


def draw_trajectory(ax: Axes, poses: NDArray, arrows: int = 60, **kwargs) -> None:
    """The path as a line with about `arrows` heading arrows along it."""
    poses = np.asarray(poses, dtype=float)
    ax.plot(poses[:, 0], poses[:, 1], "-", color=kwargs.get("color", ESTIMATE), lw=1, alpha=0.6)
    step = max(1, len(poses) // arrows)
    p = poses[::step]
    ax.quiver(
        p[:, 0],
        p[:, 1],
        np.cos(p[:, 2]),
        np.sin(p[:, 2]),
        color=kwargs.get("color", ESTIMATE),
        angles="xy",
        scale_units="xy",
        scale=kwargs.get("arrow_scale", 12.0),
        width=0.004,
        label=kwargs.get("label"),
    )


def draw_true_landmarks(ax: Axes, tag_map: Mapping[int, ArrayLike]) -> None:
    """The true landmarks as green squares, each labelled with its id away from the centre."""
    ids = sorted(tag_map)
    truth = np.array([tag_map[i] for i in ids], dtype=float)
    ax.plot(truth[:, 0], truth[:, 1], "s", color=TRUTH, ms=8, label="true landmarks (id)")
    centre = truth.mean(axis=0)
    for i, p in zip(ids, truth, strict=True):
        away = p - centre
        norm = float(np.hypot(*away))
        offset = 13.0 * away / norm if norm > 0 else np.array([0.0, 13.0])
        ax.annotate(
            str(i),
            tuple(p),
            xytext=tuple(offset),
            textcoords="offset points",
            ha="center",
            va="center",
            color=TRUTH,
            fontweight="bold",
            fontsize=FONT,
        )


def plot_map(
    ax: Axes,
    run: RunLog,
    result: ReplayResult,
    *,
    arena_half_size: float | None = None,
    true_start: ArrayLike | None = None,
    confidence: float = 0.95,
    alignment: Alignment | None = None,
) -> None:
    """The seed's Figure 2 on one axes.

    Vermillion arrows: the estimated trajectory; vermillion hollow circles: estimated landmarks
    with blue `confidence` ellipses; green squares: true landmarks with their ids; black star:
    the true start (when known). The colours are `ekfslam.viz.style`'s, safe for colour-blind
    readers. Without `alignment` the estimate is drawn as the filter holds it, before
    alignment (as the seed drew it; the vermillion labels are the estimated landmarks' ids).
    With it,
    the trajectory, landmarks and ellipses are carried by eq. (17)'s transform onto the world
    (world = R(θ0) estimate + (x0, y0), covariances R Σ Rᵀ).
    """
    if arena_half_size is not None:
        draw_arena(ax, arena_half_size)
    h = result.history
    poses = np.asarray(h.pose, dtype=float)
    rotate = np.eye(2)
    if alignment is not None:
        rotate = rotation(alignment.theta0)
        poses = (
            np.column_stack(
                [alignment.apply(poses[:, :2]), wrap_angle(poses[:, 2] + alignment.theta0)]
            )
            if len(poses)
            else poses
        )
    if len(poses):
        draw_trajectory(ax, poses, label="estimated trajectory")
    if run.meta.tag_map:
        draw_true_landmarks(ax, run.meta.tag_map)
    if result.landmarks:
        ids = sorted(result.landmarks)
        est = np.array([result.landmarks[i] for i in ids], dtype=float)
        if alignment is not None:
            est = alignment.apply(est)
        ax.plot(
            est[:, 0],
            est[:, 1],
            "o",
            mfc="none",
            mec=ESTIMATE,
            ms=10,
            mew=1.5,
            label="estimated landmarks",
        )
        for i, mean in zip(ids, est, strict=True):
            cov = rotate @ np.asarray(result.landmark_covariances[i]) @ rotate.T
            ax.add_patch(covariance_ellipse(mean, cov, confidence, color=UNCERTAINTY, lw=1.2))
            if alignment is None:  # aligned, they sit on the true ids' dots
                ax.annotate(
                    str(i),
                    tuple(mean),
                    xytext=(6, 6),
                    textcoords="offset points",
                    color=ESTIMATE,
                    fontsize=FONT,
                )
        ax.plot([], [], "-", color=UNCERTAINTY, label=f"{confidence:.0%} covariance ellipses")
    if true_start is not None:
        s = np.asarray(true_start, dtype=float)
        ax.plot(s[0], s[1], "*", color=START, ms=13, label="true start")
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
    alignment: Alignment | None = None,
    alignment_note: str | None = None,
    figsize: tuple[float, float] = (14.0, 8.0),
) -> Figure:
    """The seed's Figure 2 for one run, and beside it the same map after alignment.

    Left: the estimate before alignment, in the filter's own frame, over the true tags: the
    seed's Figure 2, whose landmarks can sit outside the walls by the start's placement error.
    Right: the same estimate after eq. (17)'s transform `alignment` (computed by the caller,
    e.g. `ekfslam.analysis.evaluation.summarize`'s), which is what the printed average error
    measures. Without an alignment only the left panel is drawn and its title says why
    (`alignment_note`, e.g. the summary's; by default: no known tag map). No pyplot state: safe
    in scripts and tests.
    """
    note = alignment_note or "the run has no known tag map"
    fig = Figure(figsize=figsize if alignment is not None else (9.0, 8.0), layout="constrained")
    # not sharex/sharey: with equal aspects the constrained layout then misplaces the labels
    axes = fig.subplots(1, 2 if alignment is not None else 1, squeeze=False)[0]
    true_start = None
    if run.groundtruth is not None and len(run.groundtruth.t):
        true_start = run.groundtruth.pose[0]
    kwargs = dict(arena_half_size=arena_half_size, true_start=true_start)
    plot_map(axes[0], run, result, **kwargs)
    before = "before alignment: the filter's own frame (the seed's Figure 2)"
    unaligned = _mean_distance(result.landmarks, run.meta.tag_map or {})
    if unaligned is not None:
        before += f"\nmean distance to the true landmarks {unaligned:.3f} m"
    if alignment is None:
        before += f"\nno aligned map: {note}"
    axes[0].set_title(before, fontsize=12)
    if alignment is not None:
        plot_map(axes[1], run, result, alignment=alignment, **kwargs)
        axes[1].set_title(
            f"after the eq. (17) alignment (x0 {alignment.x0:+.3f} m, y0 {alignment.y0:+.3f} m, "
            f"θ0 {alignment.theta0:+.3f} rad)\nmean error {alignment.mean_error:.3f} m "
            f"over {len(alignment.ids)} landmarks",
            fontsize=12,
        )
    if alignment is not None:  # the same window on both maps, so that they compare at a glance
        x = [*axes[0].get_xlim(), *axes[1].get_xlim()]
        y = [*axes[0].get_ylim(), *axes[1].get_ylim()]
        for ax in axes:
            ax.set_xlim(min(x), max(x))
            ax.set_ylim(min(y), max(y))
    fig.suptitle(title or f"EKF SLAM: {run.meta.name}", fontsize=14)
    # below the maps: inside an axes, the legend hid a landmark of the seed's runs
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=3, fontsize=FONT)
    return fig


def _mean_distance(estimated: Mapping[int, ArrayLike], truth: Mapping[int, ArrayLike]):
    common = [i for i in estimated if i in truth]
    if not common:
        return None
    return float(
        np.mean([np.hypot(*(np.asarray(estimated[i]) - np.asarray(truth[i]))) for i in common])
    )


# --- helpers for the classroom notebooks --------------------------------------------------------


def draw_tags(ax: Axes, arena: Arena, *, label: str | None = "tags (AprilTags)") -> None:
    """The arena's tags as green squares with their ids and an arrow along each face's normal."""
    pos, normals = arena.tag_positions(), arena.tag_normals()
    ax.plot(pos[:, 0], pos[:, 1], "s", color=TRUTH, ms=9, label=label)
    ax.quiver(
        pos[:, 0],
        pos[:, 1],
        normals[:, 0],
        normals[:, 1],
        color=TRUTH,
        angles="xy",
        scale_units="xy",
        scale=8.0,
        width=0.005,
    )
    for tag in arena.tags:  # ids just outside the wall, clear of the normal arrows
        offset = -14 * np.asarray(tag.normal)
        ax.annotate(
            str(tag.id),
            tag.position,
            xytext=tuple(offset),
            textcoords="offset points",
            ha="center",
            va="center",
            color=TRUTH,
            fontweight="bold",
        )


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
    kwargs.setdefault("color", UNCERTAINTY)
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

    landmark_ids : the ids in slot order (see `ekfslam.pipeline.landmark_slots`).
    Correlations are drawn on a fixed -1..1 scale so snapshots of a run can be compared; a variance
    of zero (a known start) gives a correlation of zero.
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
    ax.set_xticks(range(len(S)), names, rotation=90, fontsize=FONT)
    ax.set_yticks(range(len(S)), names, fontsize=FONT)
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
        ax.add_patch(covariance_ellipse(mu[:2], S[:2, :2], color=ESTIMATE, ls=style, alpha=alpha))
        ax.quiver(
            mu[0],
            mu[1],
            math.cos(mu[2]),
            math.sin(mu[2]),
            color=ESTIMATE,
            alpha=alpha,
            angles="xy",
            scale_units="xy",
            scale=8.0,
            width=0.006,
        )
        for k in range(len(landmark_ids)):
            l = 3 + 2 * k
            color = UNCERTAINTY if k == j else "0.5"
            ax.add_patch(
                covariance_ellipse(
                    mu[l : l + 2], S[l : l + 2, l : l + 2], color=color, ls=style, alpha=alpha
                )
            )
        if alpha == 1.0 and style == "-":
            for k, i in enumerate(landmark_ids):
                ax.annotate(
                    str(i),
                    mu[3 + 2 * k : 5 + 2 * k],
                    xytext=(8, 8),
                    textcoords="offset points",
                    fontsize=FONT,
                )
        ax.plot([], [], ls=style, color=ESTIMATE, label=f"robot, {tag} (95%)")
        ax.plot([], [], ls=style, color=UNCERTAINTY, label=f"landmark {landmark_ids[j]}, {tag}")

    for ax in (a, b, d):
        if truth is not None:
            pts = np.array([truth[i] for i in landmark_ids])
            ax.plot(pts[:, 0], pts[:, 1], "s", color=TRUTH, ms=5, label="true landmarks")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.grid(True, alpha=0.3)
    state(a, mu0, S0, "-", "prior")
    a.set_title("(a) prior: Σ after prediction (eq. 9)")
    state(b, mu0, S0, "-", "prior", alpha=0.9)  # the prior that z is weighed against
    r, phi = steps.z
    ang = mu0[2] + phi
    seen = mu0[:2] + r * np.array([math.cos(ang), math.sin(ang)])
    b.plot(
        [mu0[0], seen[0]],
        [mu0[1], seen[1]],
        "-",
        color=MEASUREMENT,
        lw=2,
        label=f"measured z: r = {r:.3f} m, φ = {phi:.3f} rad",
    )
    b.plot(*seen, "x", color=MEASUREMENT, ms=12, mew=3)
    b.plot(
        [mu0[0], mu0[lj]],
        [mu0[1], mu0[lj + 1]],
        "--",
        color=UNCERTAINTY,
        label=f"predicted ẑ (eq. 13): r = {steps.z_hat[0]:.3f} m, φ = {steps.z_hat[1]:.3f} rad",
    )
    b.set_title(
        f"(b) measurement vs prediction: ν = ({steps.nu[0]:+.3f} m, {steps.nu[1]:+.3f} rad)"
    )
    correction = steps.K @ steps.nu
    names = state_labels(landmark_ids)
    colors = [ESTIMATE] * 3 + [UNCERTAINTY if k // 2 == j else "0.6" for k in range(len(names) - 3)]
    c.bar(range(len(names)), correction * 1000.0, color=colors, label="K ν (mm, mrad for θ)")
    c.set_xticks(range(len(names)), names, rotation=90)
    c.axhline(0.0, color="k", lw=0.8)
    c.set_xlabel("state entry (eq. 1)")
    c.set_ylabel("correction K ν (mm or mrad)")
    c.set_title("(c) gain times innovation (eqs. 15-16): every correlated entry moves")
    state(d, mu0, S0, ":", "prior", alpha=0.6)
    state(d, mu1, S1, "-", "posterior")
    d.set_title("(d) posterior (eq. 16, Joseph form): ellipses shrink")
    c.legend(loc="best", fontsize=FONT, framealpha=0.85)
    # the maps' legends (up to five entries, two of them long) cover an ellipse wherever they go
    # inside the axes: under them
    for ax in (a, b, d):
        ax.legend(
            loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=FONT, frameon=False
        )
    return fig
