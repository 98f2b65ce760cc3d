"""The seed's Table 1 (eq. 17's x0, y0, θ0 and average error), formatted in one place.

Three faces of the same table: the command line's text (`python -m ekfslam run`), the tuning
panel's narrower text with an average-NIS column (`ekfslam.ui.view.status_text`), and Markdown
for the notebooks (`table1_markdown`). Each puts the seed's real-robot row beside ours when it
is given; which row that is (`ekfslam.analysis.evaluation.seed_experiment`) is the caller's.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ekfslam.errors import EkfSlamError

if TYPE_CHECKING:
    from ekfslam.analysis.evaluation import RunSummary

#: A Table 1 row: x0 (m), y0 (m), θ0 (rad), average error (m), as in `SEED_TABLE1`.
Row = Sequence[float]


@dataclass(frozen=True)
class TextLayout:
    """Column widths (characters) and titles of a text Table 1."""

    name: int  # the trajectory column, left-aligned
    number: int  # each of x0, y0, theta0
    error: int  # the average error
    error_title: str
    seed_label: str  # the name in the seed's row
    extra: int = 9  # a column after the error, in the header and our row (the panel's NIS)


COMMAND_LINE = TextLayout(22, 9, 15, "Average Error", "  seed report (real)")
PANEL = TextLayout(16, 8, 11, "Avg error", "seed (real)")


def table1_row(label: str, row: Row, layout: TextLayout = COMMAND_LINE) -> str:
    """One text row: `label`, then x0, y0, θ0 and the error with three decimals."""
    x0, y0, theta0, error = row
    n = layout.number
    return (
        f"{label:<{layout.name}}{x0:>{n}.3f}{y0:>{n}.3f}{theta0:>{n}.3f}{error:>{layout.error}.3f}"
    )


def table1_lines(
    summary: RunSummary,
    seed: Row | None = None,
    *,
    layout: TextLayout = COMMAND_LINE,
    extra: tuple[str, str] | None = None,
) -> list[str]:
    """The header, our row (or why there is no alignment) and the seed's row when given.

    extra : (title, value) of one more column after the error, e.g. the panel's average NIS.
    """
    n = layout.number
    head = (
        f"{'Trajectory':<{layout.name}}{'x0':>{n}}{'y0':>{n}}{'theta0':>{n}}"
        f"{layout.error_title:>{layout.error}}"
    )
    a = summary.alignment
    if a is None:
        row = f"{summary.name:<{layout.name}}  (no alignment: {summary.alignment_note})"
    else:
        row = table1_row(summary.name, (a.x0, a.y0, a.theta0, a.mean_error), layout)
    if extra is not None:
        head += f"{extra[0]:>{layout.extra}}"
        row += f"{extra[1]:>{layout.extra}}"
    lines = [head, row]
    if seed is not None:  # the seed's real-robot row under ours, for comparison
        lines.append(table1_row(layout.seed_label, seed, layout))
    return lines


def table1_markdown(summaries: Mapping[str, RunSummary], seed_table: Mapping[str, Row]) -> str:
    """The seed's Table 1 as a Markdown table: each of our runs beside the seed's row.

    summaries : {trajectory name ("square", ...): RunSummary with an alignment}.
    seed_table : {trajectory name: (x0, y0, θ0, average error)},
        e.g. `ekfslam.analysis.evaluation.SEED_TABLE1`.
    """
    lines = [
        "| Trajectory | x0 (m) | y0 (m) | θ0 (rad) | Average error (m) |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, summary in summaries.items():
        a = summary.alignment
        if a is None:
            raise EkfSlamError(f"run {name!r} has no alignment (no tag map?)")
        lines.append(
            _markdown_row(f"{name}, this simulation", (a.x0, a.y0, a.theta0, a.mean_error))
        )
        if name in seed_table:
            lines.append(_markdown_row(f"{name}, seed report (real robot)", seed_table[name]))
    return "\n".join(lines)


def _markdown_row(label: str, row: Row) -> str:
    return f"| {label} | " + " | ".join(f"{v:.3f}" for v in row) + " |"


def association_line(block: dict) -> str:
    """One line of ``run``'s table: its ``association`` block (`ekfslam.analysis.association`)."""
    f = block["correct_fraction"]
    share = "n/a" if f is None else f"{100 * f:.1f}%"
    return (
        f"association {block['method']}: correct {block['correct']}, wrong {block['wrong']}, "
        f"missed {block['missed']} ({share} correct), new {block['new']}, ambiguous "
        f"{block['ambiguous']}, tentative discarded {block['tentative_discarded']}"
        + (f", duplicates {len(block['duplicates'])}" if block["duplicates"] else "")
        + (f", JCBB budget hit {block['jcbb_budget_hits']}x" if block["jcbb_budget_hits"] else "")
        + f"; {block['alignment_matching']}"
    )
