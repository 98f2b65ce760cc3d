"""The team's figures: every robot's trajectory and the one map, in the true landmarks' frame
(`team_figure`); the joint state's correlations, block by block (`plot_team_covariance`); each
robot's and each landmark's ellipse of a joint state (`draw_team_state`, notebook 13).

The joint map and the trajectories are moved by eq. (17)'s alignment of the map onto the true
landmarks; where Vicon gives a robot's truth, it is drawn beside its estimate, thin and dashed.
Robots are told apart by colour (Okabe & Ito's palette, safe under colour-blindness) and by
line style, so a projector or a grey print keeps them apart too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from numpy.typing import ArrayLike

from ekfslam.geometry import rotation
from ekfslam.viz.plotting import covariance_ellipse, state_labels
from ekfslam.viz.style import FONT

#: Okabe & Ito (2008), "Color Universal Design": five hues apart under deuteranopia and protanopia.
ROBOT_COLOURS = ("#0072B2", "#E69F00", "#009E73", "#CC79A7", "#D55E00")
ROBOT_STYLES = ("-", "--", "-.", ":", (0, (5, 1, 1, 1)))


def team_figure(team, result, alignment) -> Figure:
    """The robots' aligned trajectories (and Vicon's, where given), the joint map's landmarks
    (open circles) and the true ones (black crosses)."""
    fig = Figure(figsize=(8, 8), dpi=150)
    ax = fig.add_subplot()
    R, t = rotation(alignment.theta0), np.array([alignment.x0, alignment.y0])
    for k, robot in enumerate(result.robots):
        colour, style = ROBOT_COLOURS[k % 5], ROBOT_STYLES[k % 5]
        track = result.tracks[robot]
        if robot in result.entries and len(track.t):
            xy = track.pose[:, :2] @ R.T + t
            ax.plot(xy[:, 0], xy[:, 1], color=colour, ls=style, lw=1.2, label=f"robot {robot}")
        truth = team.runs[robot].groundtruth
        if truth is not None:
            ax.plot(
                truth.pose[:, 0],
                truth.pose[:, 1],
                color=colour,
                ls=(0, (1, 2)),
                lw=0.6,
                alpha=0.8,
                label=f"robot {robot}, Vicon",
            )
    true = np.array(list(team.tag_map.values()))
    ax.plot(true[:, 0], true[:, 1], "kx", ms=9, mew=2, label="true landmarks")
    mapped = np.array([result.landmarks[i] for i in sorted(result.landmarks)]) @ R.T + t
    ax.plot(mapped[:, 0], mapped[:, 1], "o", mfc="none", mec="k", ms=11, label="joint map")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]", fontsize=FONT)
    ax.set_ylabel("y [m]", fontsize=FONT)
    ax.set_title(
        f"{result.name}: {len(result.robots)} robots, one map "
        f"(eq. 17: {alignment.mean_error:.3f} m)",
        fontsize=FONT,
    )
    ax.legend(fontsize=FONT - 2, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    return fig


def team_state_labels(rows: Mapping[int, int], landmark_ids: Sequence[int]) -> list[str]:
    """Names of a joint state's entries: x1, y1, θ1 for robot 1's block (robots in row order),
    then m{id}x, m{id}y per landmark in slot order."""
    names = []
    for robot in sorted(rows, key=rows.get):
        names += [f"x{robot}", f"y{robot}", f"θ{robot}"]
    return names + state_labels(landmark_ids)[3:]  # the map's names as the single state's


def plot_team_covariance(
    ax: Axes,
    Sigma: ArrayLike,
    rows: Mapping[int, int],
    landmark_ids: Sequence[int],
    title: str | None = None,
) -> AxesImage:
    """The correlation matrix of a joint state's Σ (d, d) on a fixed -1..1 scale, with lines
    between the robots' pose blocks and between the robots and the map.

    rows : {robot: its first row} (`TeamEKF.rows`, `TeamResult.rows`); landmark_ids : the
    landmarks in slot order (the order of `TeamResult.landmarks`). A variance of zero (a known
    start) gives a correlation of zero.
    """
    S = np.asarray(Sigma, dtype=float)
    sd = np.sqrt(np.clip(np.diag(S), 0.0, None))
    scale = np.outer(sd, sd)
    C = np.divide(S, scale, out=np.zeros_like(S), where=scale > 0)
    image = ax.imshow(C, cmap="RdBu_r", vmin=-1.0, vmax=1.0)
    names = team_state_labels(rows, landmark_ids)[: len(S)]
    ax.set_xticks(range(len(S)), names, rotation=90, fontsize=FONT)
    ax.set_yticks(range(len(S)), names, fontsize=FONT)
    for k in range(1, len(rows) + 1):  # after each pose block; the last one is the map's edge
        ax.axhline(3 * k - 0.5, color="k", lw=1.5 if k == len(rows) else 0.6)
        ax.axvline(3 * k - 0.5, color="k", lw=1.5 if k == len(rows) else 0.6)
    if title is not None:
        ax.set_title(title, fontsize=FONT)
    return image


def draw_team_state(
    ax: Axes,
    mu: ArrayLike,
    Sigma: ArrayLike,
    rows: Mapping[int, int],
    slot: Mapping[int, int],
    label: str = "",
    **style,
) -> None:
    """Each robot's 95% position ellipse and heading arrow (in its colour, `ROBOT_COLOURS` by
    row order) and each landmark's ellipse (grey) of a joint state: mu (d,), Sigma (d, d),
    rows {robot: its first row}, slot {landmark id: its first row} (`TeamEKF.rows`, `.slot`).
    `style` goes to every ellipse (``ls="--"`` for a state before an update); `label` names
    the robots and landmarks in the legend (``"before"``)."""
    mu, S = np.asarray(mu, dtype=float), np.asarray(Sigma, dtype=float)
    suffix = f", {label}" if label else ""
    for k, robot in enumerate(sorted(rows, key=rows.get)):
        r, colour = rows[robot], ROBOT_COLOURS[k % 5]
        ellipse = covariance_ellipse(mu[r : r + 2], S[r : r + 2, r : r + 2], color=colour, **style)
        ellipse.set_label(f"robot {robot}{suffix}")
        ax.add_patch(ellipse)
        heading = mu[r + 2]
        ax.annotate(
            "",
            xy=(mu[r] + 0.12 * math.cos(heading), mu[r + 1] + 0.12 * math.sin(heading)),
            xytext=(mu[r], mu[r + 1]),
            arrowprops={"arrowstyle": "->", "color": colour},
        )
    for n, (landmark, l) in enumerate(slot.items()):
        ellipse = covariance_ellipse(mu[l : l + 2], S[l : l + 2, l : l + 2], color="0.4", **style)
        if n == 0:
            ellipse.set_label(f"landmarks{suffix}")
        ax.add_patch(ellipse)
        ax.annotate(str(landmark), mu[l : l + 2], fontsize=FONT, color="0.4")
    ax.set_aspect("equal")
