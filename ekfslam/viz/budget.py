"""The realistic robot's error budget (`ekfslam.analysis.error_budget`) as a table and a figure."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ekfslam.analysis.error_budget import ErrorBudget

FONT = 12  # pt: legends, labels and ticks readable on a projector


def budget_markdown(budgets: Sequence[ErrorBudget], seed_errors: Mapping[str, float]) -> str:
    """One Markdown table, a column pair per trajectory: each source alone and all but it (mm).

    `seed_errors` : {trajectory: the seed's real-robot average error (m)}, for the last row.
    """
    head = (
        "| error source | value | "
        + " | ".join(f"{b.trajectory}: alone | {b.trajectory}: all but" for b in budgets)
        + " |"
    )
    lines = [head, "|---|---:|" + "---:|---:|" * len(budgets)]
    for k, row in enumerate(budgets[0].rows):
        cells = [f"{1000 * b.rows[k].alone:.0f} | {1000 * b.rows[k].all_but:.0f}" for b in budgets]
        lines.append(f"| {row.source} | {row.field} = {row.value:g} | " + " | ".join(cells) + " |")
    for label, value in (("none (ideal robot)", "ideal"), ("all (realistic robot)", "realistic")):
        cells = [f"{1000 * getattr(b, value):.0f} | " for b in budgets]
        lines.append(f"| {label} | | " + " | ".join(cells) + " |")
    seed = [
        f"{1000 * seed_errors[b.trajectory]:.0f} | " for b in budgets if b.trajectory in seed_errors
    ]
    if len(seed) == len(budgets):
        lines.append("| the seed's real robot | | " + " | ".join(seed) + " |")
    return "\n".join(lines)


def budget_text(budget: ErrorBudget) -> str:
    """A plain-text table of one trajectory's budget, in mm (for the command line)."""
    width = max(len(r.source) for r in budget.rows) + 2
    lines = [
        f"{budget.trajectory} (seeds {', '.join(map(str, budget.seeds))}): map error, mm",
        f"{'error source':<{width}}{'alone':>8}{'all but':>10}",
    ]
    for r in budget.rows:
        lines.append(f"{r.source:<{width}}{1000 * r.alone:>8.0f}{1000 * r.all_but:>10.0f}")
    lines.append(f"{'none (ideal)':<{width}}{1000 * budget.ideal:>8.0f}")
    lines.append(f"{'all (realistic)':<{width}}{1000 * budget.realistic:>8.0f}")
    if len(budget.realistic_by_seed) > 1:
        spread = sorted(1000 * e for e in budget.realistic_by_seed)
        median = float(np.median(spread))
        lines.append(
            f"{'  by seed':<{width}}min {spread[0]:.0f}, median {median:.0f}, max {spread[-1]:.0f}"
        )
    return "\n".join(lines)


def budget_figure(budgets: Sequence[ErrorBudget], seed_errors: Mapping[str, float]) -> Figure:
    """A panel per trajectory: for each source, the map error it makes alone and what fixing it
    saves (realistic minus all but it); the realistic robot's error and the seed's as lines."""
    fig, axes = plt.subplots(
        1,
        len(budgets),
        figsize=(7 * len(budgets), 5.5),
        layout="constrained",
        sharex=True,
        sharey=True,
        squeeze=False,
    )
    for ax, b in zip(axes[0], budgets, strict=True):
        names = [r.source for r in b.rows]
        y = range(len(names))
        alone = [100 * r.alone for r in b.rows]
        saved = [100 * (b.realistic - r.all_but) for r in b.rows]
        ax.barh(
            [k - 0.2 for k in y], alone, height=0.4, color="tab:blue", label="this source alone"
        )
        ax.barh(
            [k + 0.2 for k in y],
            saved,
            height=0.4,
            color="tab:orange",
            label="saved by fixing it (all - all but)",
        )
        ax.axvline(100 * b.realistic, color="k", lw=2, label="realistic robot (all sources)")
        seed = seed_errors.get(b.trajectory)
        if seed is not None:
            ax.axvline(100 * seed, color="tab:red", ls="--", lw=2, label="the seed's real robot")
        ax.axvline(0, color="0.5", lw=1)
        ax.set_yticks(list(y), names, fontsize=FONT)
        ax.tick_params(labelsize=FONT)
        ax.set_xlabel("average map error after eq. (17) (cm)", fontsize=FONT)
        ax.set_title(f"{b.trajectory}: ideal robot {100 * b.ideal:.1f} cm", fontsize=FONT + 1)
        ax.grid(True, axis="x", alpha=0.3)
    axes[0][0].invert_yaxis()  # the axes share y: once turns all, the first source on top
    legend: dict[str, object] = {}  # every panel's entries, once (a panel may lack the seed's)
    for ax in axes[0]:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            legend.setdefault(label, handle)
    fig.legend(
        list(legend.values()), list(legend), loc="outside lower center", ncols=2, fontsize=FONT
    )
    return fig
