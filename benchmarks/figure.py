"""The benchmark's figure: the cost of one filter step against the map size."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ekfslam.files import save_figure


def plot_costs(r: dict, path: Path) -> None:
    """Log-log plot of the per-step cost against n, both implementations, with the floor.

    r : `benchmarks.bench.run_benchmarks`' result; path : the PNG to write.
    A bare Figure, not pyplot: no backend is switched and nothing stays open.
    """
    fig = Figure(figsize=(9, 6))
    ax = fig.subplots()
    for impl, style in (("efficient", "-"), ("literal", "--")):
        for step, marker in (("predict", "o"), ("update", "s")):
            costs = r["cost_s"][impl][step]
            ns = [n for n in r["sizes"] if costs[n] is not None]
            ax.loglog(ns, [costs[n] for n in ns], style, marker=marker, label=f"{impl} {step}")
    hi = r["floor_n"]
    ax.loglog([hi], [r["floor_s"]], "kx", ms=10, label="floor: Sigma -= A @ B (rank 2)")
    ax.loglog([hi], [r["inplace_pass_s"]], "k+", ms=12, label="one pass over Sigma (*= 1.0)")
    lo = r["update_slope_between"][0]
    ns = np.array([n for n in r["sizes"] if n >= lo], dtype=float)
    ref = r["cost_s"]["efficient"]["update"][hi]
    ax.loglog(ns, ref * (ns / hi) ** 2, ":", color="grey", label="∝ n² (through the update)")
    ax.set_xlabel("landmarks in the map, n")
    ax.set_ylabel("time per step, s (median)")
    ax.set_title("EKF-SLAM: cost of one step against the map size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    save_figure(fig, path)
