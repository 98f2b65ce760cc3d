"""The consistency figure's log axes: the tick labels of a panel never run into each other
(notebook 09's heading panel, 0.5 to 7, had 0.6 0.7 0.8 0.9 1.0 stacked at 11 pt)."""

from __future__ import annotations

from types import SimpleNamespace

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg

from ekfslam.viz.consistency import plot_consistency

matplotlib.use("Agg")


def _study(linearization: str, heading: np.ndarray) -> SimpleNamespace:
    t = np.linspace(0.0, 72.0, heading.size)
    band = lambda lo, hi: np.array([lo, hi])  # noqa: E731
    return SimpleNamespace(
        t=t,
        nees_pose=3 * heading,
        nees_heading=heading,
        nis=2 * np.sqrt(heading),
        band_pose=band(2.3, 3.7),
        band_heading=band(0.65, 1.45),
        band_nis=band(1.5, 2.6),
        confidence=0.95,
        runs=50,
        linearization=linearization,
        scenario="loop",
        fraction_in_band=lambda name: 0.5,
    )


def overlapping_labels(fig) -> list[tuple[str, str]]:
    """Pairs of visible y tick labels of one axes whose boxes on the canvas overlap."""
    FigureCanvasAgg(fig).draw()
    renderer = fig.canvas.get_renderer()
    pairs = []
    for ax in fig.axes:
        ticks = ax.yaxis.get_major_ticks() + ax.yaxis.get_minor_ticks()
        shown = [
            t.label1
            for t in ticks
            if t.label1.get_visible()
            and t.label1.get_text()
            and ax.get_ylim()[0] <= t.get_loc() <= ax.get_ylim()[1]
        ]
        boxes = [(s.get_text(), s.get_window_extent(renderer)) for s in shown]
        for i, (a, box_a) in enumerate(boxes):
            pairs += [(a, b) for b, box_b in boxes[i + 1 :] if box_a.overlaps(box_b)]
    return pairs


def test_the_log_panels_tick_labels_do_not_overlap() -> None:
    rising = np.concatenate([np.linspace(0.55, 1.4, 300), np.linspace(1.4, 6.6, 200)])
    flat = np.clip(rising, 0.55, 1.5)
    fig = plot_consistency([_study("standard", rising), _study("fej", flat)])
    assert overlapping_labels(fig) == []
    labels = {t.get_text() for t in fig.axes[1].get_yticklabels(minor=True) if t.get_text()}
    assert {"2", "3", "5"} <= labels  # still a scale to read off
