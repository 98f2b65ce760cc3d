"""The team's figure: every robot's trajectory and the one map, in the true landmarks' frame.

The joint map and the trajectories are moved by eq. (17)'s alignment of the map onto the true
landmarks; where Vicon gives a robot's truth, it is drawn beside its estimate, thin and dashed.
Robots are told apart by colour (Okabe & Ito's palette, safe under colour-blindness) and by
line style, so a projector or a grey print keeps them apart too.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ekfslam.geometry import rotation
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
