"""The wrong associations of the stress study (issue 16), one panel per method.

Each panel draws the true tags, the robot's true path and, in red, a line from where the robot
was to the true tag a sighting was taken for, for every sighting associated wrongly: with NN,
bundles of them at the pairs where the loop closed; with JCBB, few or none.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from ekfslam.viz.style import FONT

if TYPE_CHECKING:
    from ekfslam.analysis.association_stress import StressStudy


def plot_wrong_associations(study: StressStudy, methods=("nn", "jcbb")) -> Figure:
    """Side-by-side panels of the first run's wrong associations (`StressStudy.wrong`)."""
    fig = Figure(figsize=(5.0 * len(methods), 5.2), layout="constrained")
    axes = fig.subplots(1, len(methods), squeeze=False)[0]
    tags = np.array(list(study.tags.values())).reshape(-1, 2)
    for ax, m in zip(axes, methods, strict=True):
        case = study.cases[m][0]
        segments = study.wrong[m]
        ax.plot(*study.path.T, color="0.6", lw=0.8, label="true path")
        if len(segments):
            ax.add_collection(
                LineCollection(
                    segments,
                    colors="tab:red",
                    linewidths=0.6,
                    alpha=0.5,
                    label=f"wrong association ({len(segments)})",
                )
            )
        ax.plot(*tags.T, "ks", ms=4, label="true tags")
        fraction = "–" if case.correct_fraction is None else f"{case.correct_fraction:.1%}"
        error = "–" if case.aligned_error is None else f"{case.aligned_error:.3f} m"
        ax.set_title(
            f"{m}: {fraction} correct, {case.wrong} wrong\naligned map error {error}"
            f" (known: {study.cases['known'][0].aligned_error:.3f} m)",
            fontsize=FONT,
        )
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.legend(loc="center", fontsize=FONT)
    fig.suptitle(f"stress scenario, seed {study.seeds[0]}: close pairs of tags, a drifting loop")
    return fig
