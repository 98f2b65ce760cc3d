"""The figures told apart by a colour-blind reader: the colours the figures actually draw (read
from their legends' artists), simulated under deuteranopia and protanopia, stay apart.

The simulation is Machado, Oliveira & Fernandes (2009), "A Physiologically-based Model for
Simulation of Color Vision Deficiency", IEEE TVCG 15(6): their severity-1.0 matrices, applied to
linear RGB. The distance is CIELAB's ΔE*ab (CIE 1976, D65 white). Two legend entries of
different colours must stay at least `MIN_DELTA_E` apart under each; entries of one colour (one
role: the estimated path and the estimated landmarks) must differ by marker or line style. The
old red estimate and green truth of Figure 2 came within 7 under deuteranopia: one olive.
"""

from __future__ import annotations

import itertools
from pathlib import Path
from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from ekfslam.viz.style import ESTIMATE, MEASUREMENT, START, TRUTH, UNCERTAINTY

matplotlib.use("Agg")

#: Machado et al. 2009, Table 1, severity 1.0 (linear RGB in, linear RGB out)
PROTANOPIA = np.array(
    [
        [0.152286, 1.052583, -0.204868],
        [0.114503, 0.786281, 0.099216],
        [-0.003882, -0.048116, 1.051998],
    ]
)
DEUTERANOPIA = np.array(
    [
        [0.367322, 0.860646, -0.227968],
        [0.280085, 0.672501, 0.047413],
        [-0.011820, 0.042940, 0.968881],
    ]
)
SIMULATIONS = {"normal": np.eye(3), "deuteranopia": DEUTERANOPIA, "protanopia": PROTANOPIA}
#: ΔE*ab: about 2.3 is just noticeable; 20 is two clearly different colours
MIN_DELTA_E = 20.0
#: sRGB (linear) to XYZ, D65
SRGB_TO_XYZ = np.array(
    [
        [0.4124564, 0.3575761, 0.1804375],
        [0.2126729, 0.7151522, 0.0721750],
        [0.0193339, 0.1191920, 0.9503041],
    ]
)
D65 = np.array([0.95047, 1.0, 1.08883])


def linear(rgb) -> np.ndarray:
    c = np.asarray(rgb, dtype=float)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def lab(linear_rgb: np.ndarray) -> np.ndarray:
    t = SRGB_TO_XYZ @ np.clip(linear_rgb, 0.0, 1.0) / D65
    f = np.where(t > (6 / 29) ** 3, np.cbrt(t), t / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def delta_e(a, b, simulation: np.ndarray) -> float:
    """ΔE*ab between colours `a` and `b` as seen through `simulation`."""
    la, lb = (lab(simulation @ linear(to_rgb(c))) for c in (a, b))
    return float(np.linalg.norm(la - lb))


def entries(legend) -> list[tuple[str, tuple, str]]:
    """(label, the colour a reader sees, the shape) of each legend entry."""
    found = []
    for handle, text in zip(legend.legend_handles, legend.get_texts(), strict=True):
        if isinstance(handle, Line2D):
            marker = handle.get_marker()
            hollow = str(handle.get_markerfacecolor()) == "none"
            shown = marker not in (None, "None", "", " ")
            colour = handle.get_markeredgecolor() if shown and hollow else handle.get_color()
            shape = f"line {handle.get_linestyle()} marker {marker} hollow {hollow}"
        elif isinstance(handle, Patch):
            colour = handle.get_edgecolor() if not handle.get_fill() else handle.get_facecolor()
            shape = f"patch fill {handle.get_fill()}"
        else:  # a collection: the quiver's arrows, a scatter
            faces = handle.get_facecolor()
            colour = faces[0] if len(faces) else handle.get_edgecolor()[0]
            shape = type(handle).__name__
        found.append((text.get_text(), to_rgb(colour), shape))
    return found


def apart(legend_entries) -> list[str]:
    """What a colour-blind reader could not tell apart in one legend."""
    bad = []
    for (la, ca, sa), (lb, cb, sb) in itertools.combinations(legend_entries, 2):
        if delta_e(ca, cb, np.eye(3)) < 1.0:  # one colour, one role: the shape must differ
            if sa == sb:
                bad.append(f"{la!r} and {lb!r}: one colour and one shape ({sa})")
            continue
        for name, simulation in SIMULATIONS.items():
            d = delta_e(ca, cb, simulation)
            if d < MIN_DELTA_E:
                bad.append(f"{la!r} and {lb!r} under {name}: ΔE {d:.1f}")
    return bad


def test_the_simulation_and_the_distance_are_the_published_ones():
    # white and black are fixed points of the simulations; ΔE of black to white is 100
    for simulation in SIMULATIONS.values():
        assert delta_e("white", "black", simulation) == pytest.approx(100.0, abs=0.1)
    # the pair this test was written for: matplotlib's red and green, one olive to a deuteranope
    assert delta_e("tab:red", "tab:green", np.eye(3)) > 100
    assert delta_e("tab:red", "tab:green", DEUTERANOPIA) < 10
    assert apart([("estimate", to_rgb("tab:red"), "o"), ("truth", to_rgb("tab:green"), "s")])


def test_the_roles_colours_stay_apart_under_deuteranopia_and_protanopia():
    roles = {"estimate": ESTIMATE, "truth": TRUTH, "uncertainty": UNCERTAINTY, "start": START}
    assert MEASUREMENT in roles.values()  # drawn where the start is not: one black
    for (a, ca), (b, cb) in itertools.combinations(roles.items(), 2):
        for name, simulation in SIMULATIONS.items():
            assert delta_e(ca, cb, simulation) >= MIN_DELTA_E, (a, b, name)


def test_figure_2s_legend_is_told_apart():
    from ekfslam import read_run
    from ekfslam.analysis.alignment import align
    from ekfslam.core.noise import default_config, default_noise
    from ekfslam.pipeline import replay
    from ekfslam.viz.plotting import figure2

    run = read_run(Path(__file__).resolve().parents[2] / "data" / "runs" / "octagon-2laps")
    result = replay(run, default_noise(run), default_config(run))
    fig = figure2(
        run, result, arena_half_size=0.75, alignment=align(result.landmarks, run.meta.tag_map)
    )
    (legend,) = fig.legends
    found = entries(legend)
    labels = [label for label, _, _ in found]
    assert {"estimated trajectory", "estimated landmarks", "true landmarks (id)"} <= set(labels)
    assert apart(found) == []


def test_the_consistency_figures_curves_are_told_apart():
    from ekfslam.viz.consistency import plot_consistency

    t = np.linspace(0.0, 60.0, 200)
    studies = [
        SimpleNamespace(
            t=t,
            nees_pose=3.0 + k + 0 * t,
            nees_heading=1.0 + k + 0 * t,
            nis=2.0 + k + 0 * t,
            band_pose=np.array([2.3, 3.7]),
            band_heading=np.array([0.65, 1.45]),
            band_nis=np.array([1.5, 2.6]),
            confidence=0.95,
            runs=50,
            linearization=lin,
            scenario="loop",
            fraction_in_band=lambda name: 0.5,
        )
        for k, lin in enumerate(("standard", "fej", "invariant"))
    ]
    fig = plot_consistency(studies)
    for ax in fig.axes:
        found = entries(ax.get_legend())
        assert len(found) == 4  # the band and the three linearizations
        assert apart(found) == []
