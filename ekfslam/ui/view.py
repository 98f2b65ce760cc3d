"""The live panel's figure: `TuningView`, built once, whose artists `show` moves in place.

Left, the seed's Figure 2; right, the NIS of every update; above, the Table 1 row
(`status_text`). `ekfslam.ui.tuning.Tuner` feeds it a replay per setting and calls `redraw`.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse
from matplotlib.transforms import offset_copy

from ekfslam.analysis.evaluation import RunSummary
from ekfslam.core.filter.config import CHI2_2DOF_99
from ekfslam.core.filter.history import Outcome
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import ReplayResult
from ekfslam.ui.blit import Blitter, can_blit
from ekfslam.ui.glyphs import CachedGlyphText
from ekfslam.viz.plotting import ellipse_parameters
from ekfslam.viz.style import ESTIMATE, FONT, START, TRUTH, UNCERTAINTY
from ekfslam.viz.tables import PANEL, Row, table1_lines

TITLE_PT = 9.5  # the Table 1 text above the axes (points)

#: The NIS axis starts here (smaller values are drawn on it): decades of tiny NIS say nothing.
NIS_FLOOR = 1e-2


#: How both legends sit under their axes, off the data.
UNDER_AXES = {"fontsize": FONT, "frameon": False, "handlelength": 1.5, "columnspacing": 1.0}


class TuningView:
    """The panel's figure: built once, then `show` moves its artists (never adds axes).

    Left, the seed's Figure 2: estimated path (red) and true path (grey), estimated landmarks
    (red circles) with 95% ellipses (blue), true tags (green), true start (blue dot). Right, the
    NIS νᵀS⁻¹ν of each update over time (eqs. 13-15) on a log scale, with the gate and the
    χ²(2) mean 2 that a consistent filter averages. Title: the Table 1 row and the average NIS.

    Drawing is most of an update's time, so the figure avoids what costs without showing
    anything: no layout engine, and the NIS axis plots log10(NIS) on a linear axis with plain
    decade labels (a log-scale axis transforms every point and typesets every label each draw).
    `redraw` then draws only the data over a cached background (`blit`, default: on a canvas
    that shows in a browser, ipympl's) or asks the canvas for a full draw.
    """

    def __init__(self, figure: Figure, blit: bool | None = None) -> None:
        self.figure = fig = figure
        # A fixed layout: constrained layout would re-measure every tick label on every redraw
        # (about half the drawing time here), and the boxes must not move while a slider does.
        fig.set_layout_engine("none")
        # The legends sit under their axes, off the data: in the map's top corner the legend hid
        # two or three tags of a MRCLAM robot, and in the NIS plot the gated points
        fig.subplots_adjust(left=0.09, right=0.985, bottom=0.2, top=0.875, wspace=0.22)
        self.map_ax, self.nis_ax = fig.subplots(1, 2, width_ratios=(1.45, 1))
        ax = self.map_ax
        # The truth changes only with the run: drawn with the cached background (see `_truth`),
        # so under everything a move draws, the ellipses included (zorder 0.9 < a patch's 1):
        # a full draw stacks them the same way.
        (self.true_path,) = ax.plot([], [], "--", color="0.55", lw=1, label="true path", zorder=0.9)
        (self.path,) = ax.plot([], [], "-", color=ESTIMATE, lw=1.2, label="estimated path")
        (self.true_tags,) = ax.plot([], [], "s", color=TRUTH, ms=8, label="true tags", zorder=0.9)
        self.tags = ax.scatter(
            np.empty(0),
            np.empty(0),
            s=90,
            facecolors="none",
            edgecolors=ESTIMATE,
            linewidths=1.5,
            label="estimated tags",
        )
        (self.start,) = ax.plot([], [], "*", color=START, ms=11, label="true start")
        ax.plot([], [], "-", color=UNCERTAINTY, label="95% ellipses")
        self.ellipses: list[Ellipse] = []
        ax.set_aspect("equal", adjustable="box")
        ax.locator_params(nbins=5)  # every tick label is typeset again on every redraw
        ax.set(xlabel="x (m)", ylabel="y (m)", title="map and path (Figure 2)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, **UNDER_AXES)
        n = self.nis_ax
        (self.accepted,) = n.plot([], [], ".", color=UNCERTAINTY, ms=3, label="accepted")
        (self.rejected,) = n.plot([], [], "x", color=ESTIMATE, ms=4, label="rejected by gate")
        self.gate_line = n.axhline(math.log10(CHI2_2DOF_99), color=ESTIMATE, lw=1, label="gate")
        n.axhline(math.log10(2.0), color="k", ls="--", lw=1, label="χ²(2) mean = 2")
        n.set(
            xlabel="time since the start (s)",
            ylabel="NIS (log scale)",
            title="NIS of each update (eqs. 13-15)",
        )
        n.grid(True, alpha=0.3)
        n.legend(loc="upper right", bbox_to_anchor=(1.0, -0.1), ncol=2, **UNDER_AXES)
        # The Table 1 header never changes: a suptitle drawn with the background; the row under
        # it is data (typesetting monospace text is a good part of a blitted move).
        self.header = fig.suptitle("", family="monospace", fontsize=TITLE_PT)
        below = offset_copy(fig.transFigure, fig, y=-TITLE_PT * 1.2, units="points")
        # (its glyphs rasterised once: `ekfslam.ui.glyphs`, the same pixels as a Text's)
        self.text = fig.add_artist(
            CachedGlyphText(
                0.5,
                0.98,
                "",
                family="monospace",
                fontsize=TITLE_PT,
                ha="center",
                va="top",
                transform=below,
            )
        )
        self._decades, self._limits_set = (0, 0), False
        self._truth_of: RunLog | None = None  # the run whose truth the artists show
        self._truth_xy = (np.empty((0, 2)), np.empty((0, 2)))
        self._truth_version = 0  # one more each time the true path or tags change
        data = [self.path, self.tags, self.start, self.accepted]
        data += [self.rejected, self.gate_line, self.text]
        self.blitter = (
            Blitter(
                fig,
                lambda: [*data, *self.ellipses],
                [ax.get_legend(), n.get_legend()],
                lambda: (
                    ax.get_xlim(),
                    ax.get_ylim(),
                    n.get_xlim(),
                    n.get_ylim(),
                    self._decades,
                    self.header.get_text(),
                    self._truth_version,
                ),
            )
            if (can_blit(fig) if blit is None else blit)
            else None
        )

    def redraw(self) -> None:
        """Show the artists' new state: blit the data, or ask the canvas for a full draw."""
        if self.blitter is not None:
            self.blitter.redraw()
        else:
            self.figure.canvas.draw_idle()

    def show(self, run: RunLog, result: ReplayResult, summary: RunSummary) -> None:
        """Move every artist to this replay's data (in place; the canvas is not drawn here).

        A run without ground truth (a MRCLAM robot of Dataset 1 or 4, a student's robot) started
        at a nominal pose, not where the robot stood: its estimate is drawn after eq. (17), and
        the blue dot is the start eq. (17) recovers. With ground truth the estimate is drawn as
        the filter made it (the seed's Figure 2).
        """
        h = result.history
        gt_xy, truth = self._truth(run)
        a = summary.alignment if not len(gt_xy) else None
        path = h.pose[:, :2] if a is None else a.apply(h.pose[:, :2])
        self.path.set_data(path[:, 0], path[:, 1])
        start = gt_xy[:1] if a is None else np.asarray(summary.start_pose)[None, :2]
        self.start.set_data(start[:, 0], start[:, 1])
        ids = sorted(result.landmarks)
        est = np.array([result.landmarks[i] for i in ids]).reshape(-1, 2)
        est = est if a is None or not len(est) else a.apply(est)
        self.tags.set_offsets(est)
        while len(self.ellipses) < len(ids):  # a pool: a run with more landmarks adds patches
            patch = Ellipse((0, 0), 0, 0, fill=False, color=UNCERTAINTY, lw=1.2)
            self.ellipses.append(self.map_ax.add_patch(patch))
        turn = 0.0 if a is None else math.degrees(a.theta0)  # eq. (17) turns the ellipses too
        for k, patch in enumerate(self.ellipses):
            patch.set_visible(k < len(ids))
            if k < len(ids):
                w, hgt, angle = ellipse_parameters(result.landmark_covariances[ids[k]])
                patch.set(center=tuple(est[k]), width=w, height=hgt, angle=angle + turn)
        self._map_limits(np.vstack([truth, gt_xy]), np.vstack([est, path]))
        self._show_nis(result)
        header, row = status_text(summary).splitlines()[:2]
        if self.header.get_text() != header:  # (a new header redraws the background: `key`)
            self.header.set_text(header)
        self.text.set_text(row)

    def _truth(self, run: RunLog) -> tuple[np.ndarray, np.ndarray]:
        """The true path and tags of `run` (empty without them), set on their artists only when
        they differ from those shown: a change redraws the background (`key`)."""
        if run is self._truth_of:
            return self._truth_xy
        gt = run.groundtruth
        gt_xy = gt.pose[:, :2] if gt is not None and len(gt.t) else np.empty((0, 2))
        tags = run.meta.tag_map or {}
        truth = np.array([tags[i] for i in sorted(tags)]).reshape(-1, 2)
        self._truth_of, self._truth_xy = run, (gt_xy, truth)
        shown = (np.column_stack(a.get_data()) for a in (self.true_path, self.true_tags))
        if not all(map(np.array_equal, shown, (gt_xy, truth))):
            self.true_path.set_data(gt_xy[:, 0], gt_xy[:, 1])
            self.true_tags.set_data(truth[:, 0], truth[:, 1])
            self._truth_version += 1
        return gt_xy, truth

    def _map_limits(self, truth: np.ndarray, estimate: np.ndarray) -> None:
        # Follow a diverging estimate only so far (twice the true scene): the map stays readable.
        ref = truth if len(truth) else estimate
        lo, hi = ref.min(axis=0), ref.max(axis=0)
        span = max(float(np.max(hi - lo)), 0.5)
        finite = estimate[np.isfinite(estimate).all(axis=1)]
        if len(finite):
            lo = np.maximum(np.minimum(lo, finite.min(axis=0)), lo - span)
            hi = np.minimum(np.maximum(hi, finite.max(axis=0)), hi + span)
        # equal spans keep the equal-aspect box the same size from one update to the next
        half = 0.56 * max(float(np.max(hi - lo)), 0.5)
        centre = 0.5 * (lo + hi)
        # Keep the limits while the scene still fits in them and fills most of them: new
        # limits redraw every tick label (ekfslam.ui.blit), a wiggle of a millimetre included.
        (x0, x1), (y0, y1) = self.map_ax.get_xlim(), self.map_ax.get_ylim()
        shown, shown_half = np.array([x0 + x1, y0 + y1]) / 2, (x1 - x0) / 2
        if self._limits_set:
            fits = np.all(np.abs(centre - shown) + half / 1.12 <= shown_half)
            if fits and half >= 0.8 * shown_half:
                return
            half *= 1.1  # room for the next wiggle (a drifting MRCLAM path moves by decimetres)
        self._limits_set = True
        self.map_ax.set_xlim(centre[0] - half, centre[0] + half)
        self.map_ax.set_ylim(centre[1] - half, centre[1] + half)

    def _show_nis(self, result: ReplayResult) -> None:
        h = result.history
        # time since the run's start: a MRCLAM log's clock is Unix time (1.2e9 s), which would
        # leave the axis an offset label and ticks of +6200 s
        t0 = float(h.t[0]) if len(h.t) else 0.0
        for line, outcome in ((self.accepted, Outcome.ACCEPTED), (self.rejected, Outcome.REJECTED)):
            mask = h.outcome_mask(outcome)
            line.set_data(h.obs_t[mask] - t0, np.log10(np.maximum(h.obs_nis[mask], NIS_FLOOR)))
        gate = result.config.gate
        self.gate_line.set_visible(gate is not None)
        self.gate_line.set_ydata([math.log10(gate or 1.0)] * 2)
        nis = h.obs_nis[np.isfinite(h.obs_nis)]
        top = max(math.ceil(math.log10(max(float(nis.max()), 1.0))) if len(nis) else 2, 2)
        if self._decades[1] - 1 == top:  # one decade less: keep it as headroom. Settings on
            top = self._decades[1]  # both sides of a decade would redraw the axis every move
        bottom = round(math.log10(NIS_FLOOR))
        self.nis_ax.set_ylim(bottom - 0.2, top + 0.2)
        if (bottom, top) != self._decades:  # the decade labels change only with the range
            self._decades = (bottom, top)
            step = max(1, math.ceil((top - bottom) / 7))
            ticks = list(range(bottom, top + 1, step))
            self.nis_ax.set_yticks(ticks, [f"{10.0**k:g}" for k in ticks])
        span = float(h.t[-1]) - t0 if len(h.t) else 1.0
        self.nis_ax.set_xlim(0.0, span + 1e-9)


def status_text(summary: RunSummary, seed: Row | None = None) -> str:
    """The Table 1 row of a replay (eq. 17), its average NIS and its update counts, 3 lines;
    with `seed` (the seed's real-robot row), that row under ours, 4 lines. A run without ground
    truth gets one more line: why it has no ATE, and the start eq. (17) recovers."""
    nis = "-" if summary.nis_mean is None else f"{summary.nis_mean:.2f}"
    lines = table1_lines(summary, seed, layout=PANEL, extra=("avg NIS", nis))
    counts = (
        f"updates accepted {summary.accepted}, rejected {summary.rejected}, "
        f"initialised {summary.initialised}, refused {summary.refused}"
        + (f", singular S {summary.singular}" if summary.singular else "")
        + ("" if summary.diagnosis is None else f"; diagnosis: {summary.diagnosis.verdict}")
    )
    if summary.ate_note is None:
        return "\n".join([*lines, counts])
    start = (
        ""
        if summary.start_pose is None
        else " (x, y, theta) = ({:.3f} m, {:.3f} m, {:+.3f} rad)".format(*summary.start_pose)
    )
    truth = f"no ground truth, no ATE: the map is scored after eq. (17); recovered start{start}"
    return "\n".join([*lines, counts, truth if start else "no ground truth, no ATE"])
