"""Figures of the consistency studies: NEES and NIS against their chi-square bands.

`plot_consistency` draws a Monte Carlo study (`ekfslam.analysis.consistency.consistency`),
`plot_mrclam_nees` the pose NEES of MRCLAM's robots against Vicon
(`ekfslam.analysis.mrclam_consistency.mrclam_consistency`). The studies compute; these draw what
they hold, bands and confidence included. No pyplot state: safe in scripts and tests.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import FuncFormatter, ScalarFormatter

from ekfslam.viz.style import ESTIMATE, FONT, TRUTH, UNCERTAINTY

if TYPE_CHECKING:
    from ekfslam.analysis.consistency import Consistency
    from ekfslam.analysis.mrclam_consistency import MrclamConsistency


#: One colour per linearisation, in every consistency figure.
#: Okabe & Ito's (`ekfslam.viz.style`): apart under simulated deuteranopia and protanopia, where
#: the old red and blue curves ran together; each has its own line style too.
COLORS = {"standard": ESTIMATE, "fej": UNCERTAINTY, "invariant": TRUTH}
STYLES = {"standard": "-", "fej": "--", "invariant": "-."}


def plot_consistency(
    results: Consistency | Iterable[Consistency], title: str | None = None, figsize=(9.0, 9.0)
) -> Figure:
    """Average pose NEES, heading NEES and NIS against their 95% bands, one line per result.

    results : a `Consistency` or a sequence of them (e.g. standard and FEJ on one scenario).
    """
    results = list(results) if isinstance(results, Iterable) else [results]
    fig = Figure(figsize=figsize, layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    panels = (
        ("nees_pose", "pose NEES (3 dof)"),
        ("nees_heading", "heading NEES (1 dof)"),
        ("nis", "NIS (2 dof)"),
    )
    for ax, (name, label) in zip(axes, panels, strict=True):
        r0 = results[0]
        band = getattr(r0, "band_" + name.removeprefix("nees_"))
        band = np.broadcast_to(band[:, None] if band.ndim == 1 else band, (2, len(r0.t)))
        ok = np.isfinite(getattr(r0, name))  # NIS exists only at camera frames
        ax.fill_between(
            r0.t[ok],
            band[0, ok],
            band[1, ok],
            color="0.85",
            label=f"{r0.confidence:.0%} band for {r0.runs} runs",
        )
        for r in results:
            ax.plot(
                r.t[ok],
                getattr(r, name)[ok],
                lw=1.0,
                color=COLORS.get(r.linearization),
                ls=STYLES.get(r.linearization, "-"),
                label=f"{r.linearization}: {r.fraction_in_band(name):.0%} of steps in band",
            )
        ax.set_ylabel(f"average {label}")
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(ScalarFormatter())  # 3, not 3 x 10^0
        ax.grid(True, alpha=0.3, which="both")
        ax.legend(loc="upper left", fontsize=FONT)
    axes[-1].set_xlabel("time (s)")
    for ax in axes:  # once the limits are final: how many minor labels fit depends on them
        ax.yaxis.set_minor_formatter(_minor_labels(ax))
    fig.suptitle(title or f"Consistency on the {results[0].scenario} scenario")
    return fig


def _minor_labels(ax) -> FuncFormatter:
    """Labels for a log axis's minor ticks: every one (3, 4, 5, ...) when the axis spans under
    half a decade, else only 2, 3 and 5 x 10^k, so that 0.6, 0.7, 0.8, 0.9 below a major 1 do not
    run into each other at 11 pt."""
    low, high = ax.get_ylim()
    decades = np.log10(high / low) if low > 0 and high > low else 1.0
    keep = None if decades < 0.5 else {2, 3, 5}

    def label(value: float, _pos: int) -> str:
        mantissa = round(value / 10.0 ** np.floor(np.log10(value) + 1e-9))
        return f"{value:g}" if keep is None or mantissa in keep else ""

    return FuncFormatter(label)


def plot_mrclam_nees(study: MrclamConsistency, figsize=None, floor: float = 0.01) -> Figure:
    """Pose NEES over time, one panel per robot, each linearization a line; log y, shared.

    The grey band is the single-run 95% chi-square(3) interval, the dashed line the ideal 3.
    Values below `floor` (NEES of a few 1e-5 occur right after the start) are drawn at it.
    """
    robots = study.robots
    fig = Figure(figsize=figsize or (9.0, 1.5 + 1.7 * len(robots)), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(robots), 1, sharex=True, sharey=True))
    for ax, robot in zip(axes, robots, strict=True):
        ax.axhspan(
            *study.interval, color="0.88", label=f"{study.confidence:.0%} interval for one run"
        )
        ax.axhline(study.ideal, color="k", ls="--", lw=1, label=f"ideal mean {study.ideal:g}")
        stats = []
        for lin in study.linearizations:
            r = study.get(robot, lin)
            minutes = (r.t - r.t[0]) / 60.0
            ax.plot(
                minutes,
                np.maximum(r.nees, floor),
                lw=0.6,
                color=COLORS.get(lin),
                ls=STYLES.get(lin, "-"),
                label=lin,
            )
            stats.append(f"{lin} mean {r.mean:.1f}, {r.fraction_in_interval:.0%} in interval")
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        ax.set_ylabel("pose NEES")
        ax.set_title(f"robot {robot}: " + "; ".join(stats), loc="left", fontsize=FONT)
        ax.grid(True, alpha=0.3, which="major")
    axes[0].set_ylim(bottom=floor)
    axes[-1].set_xlabel("time since the first command (min)")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=4)
    fig.suptitle(f"Pose NEES against Vicon, noise '{study.noise_name}'")
    return fig
