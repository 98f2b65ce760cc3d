"""Live tuning, the logic: R and Q settings that re-run the replay and redraw a figure in place.

Three layers, each ordinary code, tested without a browser:
- `TunerSettings` and `apply_changes`: widget values -> `NoiseConfig` (R of eq. 9, Q of eq. 11)
  and `FilterConfig` (landmark initialisation, NIS gate).
- `TuningView`: one figure built once (the seed's Figure 2 on the left, the NIS of every update on
  the right, a Table 1 row as its title) whose artists `show` updates in place.
- `Tuner`: holds the runs and the current settings, asks its injected compute (by default
  `ekfslam.analysis.evaluation.replay_and_summarize`) for the replay and its score, updates the
  view and calls ``canvas.draw_idle()``; changes are coalesced (`ekfslam.ui.coalescer`), so at
  most one replay runs and one waits. `ekfslam.ui.widgets.TuningPanel` is its ipywidgets face.

Errors: an exception in a widget callback is logged by the kernel where no student sees it, so
the panel shows it in an Output widget and keeps the last good figure; a bare `Tuner` re-raises.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields, replace
from functools import partial
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse

from ekfslam.analysis.evaluation import RunSummary, replay_and_summarize
from ekfslam.core.filter.config import CHI2_2DOF_99, FilterConfig, chi2_2dof_quantile
from ekfslam.core.filter.history import Outcome
from ekfslam.core.noise import NoiseConfig, default_noise
from ekfslam.errors import InputError
from ekfslam.logs.runlog import RunLog, read_run
from ekfslam.pipeline import ReplayResult
from ekfslam.ui.coalescer import Coalescer
from ekfslam.viz.plotting import ellipse_parameters
from ekfslam.viz.tables import PANEL, Row, table1_lines

#: A run to offer in the panel: a function that loads it (called once, then cached).
RunSource = Callable[[], RunLog]
#: What the tuner computes for a setting: the replay and its score (the view only draws them).
Compute = Callable[[RunLog, NoiseConfig, FilterConfig], tuple[ReplayResult, RunSummary]]

#: Where `seed_runs` looks by default: data/runs of the source checkout this package runs from.
#: An installed wheel ships no runs; `seed_runs` then says so and asks for the folder.
RUNS_DIR = Path(__file__).resolve().parents[2] / "data" / "runs"
SEED_RUNS = ("square-2laps", "octagon-2laps")
DEFAULT_FIGSIZE = (9.0, 6.0)
#: NIS gates offered (chi-square, 2 dof); 0 turns gating off, as on the command line.
GATES = {
    "off": 0.0,
    "95% (5.99)": chi2_2dof_quantile(0.95),
    "99% (9.21)": CHI2_2DOF_99,
    "99.9% (13.8)": chi2_2dof_quantile(0.999),
}
#: The NIS axis starts here (smaller values are drawn on it): decades of tiny NIS say nothing.
NIS_FLOOR = 1e-2


@dataclass(frozen=True)
class LogSlider:
    """One log-scale slider over a `NoiseConfig` field: values 10**lo .. 10**hi in `unit`.

    One keyboard step moves the exponent by `step` decades (0.1: a factor 10**0.1 ≈ 1.26).
    """

    field: str
    label: str
    unit: str
    lo: float
    hi: float
    step: float = 0.1

    def grid(self, value: float) -> tuple[float, float]:
        """Exponent range (min, max) covering lo..hi whose step grid passes through `value`.

        The browser's slider snaps its value to min + k * step and sends the snapped value
        back: 0.03 would silently become 10**-1.5 = 0.0316 as soon as the panel is shown.
        """
        e = math.log10(value)
        below = max(0, math.ceil((e - self.lo) / self.step - 1e-9))
        above = max(0, math.ceil((self.hi - e) / self.step - 1e-9))
        return e - below * self.step, e + above * self.step


SLIDERS = (
    LogSlider("sigma_x", "R: σx", "m/√s", -4.0, 0.0),
    LogSlider("sigma_y", "R: σy", "m/√s", -4.0, 0.0),
    LogSlider("sigma_theta", "R: σθ", "rad/√s", -4.0, 0.0),
    LogSlider("sigma_range", "Q: σr", "m", -3.0, 0.0),
    LogSlider("sigma_bearing", "Q: σφ", "rad", -3.0, 0.0),
)

SPECS = {spec.field: spec for spec in SLIDERS}


@dataclass(frozen=True)
class TunerSettings:
    """Everything the panel lets a student change: the run's name, R and Q, the filter options."""

    run: str
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    config: FilterConfig = field(default_factory=FilterConfig)


def apply_changes(settings: TunerSettings, changes: Mapping[str, object]) -> TunerSettings:
    """New settings from widget values: ``run``, a `NoiseConfig` field (a slider's value in its
    units, not its exponent), ``init`` ("inverse" or "seed") or ``gate`` (a NIS threshold; 0 or
    None is off). Raises ValueError for an unknown name or a value the configs refuse."""
    noise = {k: float(v) for k, v in changes.items() if k in {f.name for f in fields(NoiseConfig)}}
    config: dict[str, object] = {}
    if "init" in changes:
        config["init"] = changes["init"]
    if "gate" in changes:
        config["gate"] = float(changes["gate"]) if changes["gate"] else None
    unknown = set(changes) - set(noise) - set(config) - {"run"}
    if unknown:
        raise ValueError(f"unknown setting(s) {sorted(unknown)}")
    return TunerSettings(
        run=str(changes.get("run", settings.run)),
        noise=replace(settings.noise, **noise),
        config=replace(settings.config, **config),
    )


def seed_runs(folder: str | Path | None = None) -> dict[str, RunSource]:
    """The simulated seed runs (square and octagon, two laps) in `folder`, as lazy loaders.

    folder : default `RUNS_DIR`, the checkout's data/runs. Raises InputError when it is not
    there (an installed package has no data/runs): pass the folder of a checkout instead.
    Hook for more: any ``{name: loader}`` works, e.g. a MRCLAM robot
    ``{**seed_runs(), "mrclam7-r1": lambda: ekfslam.logs.mrclam.load.load_mrclam(path, 1)[0]}``.
    """
    folder = Path(RUNS_DIR if folder is None else folder)
    if not folder.is_dir():
        raise InputError(
            folder, None, "run folder not found (an installed ekfslam ships no data/runs); "
            "pass seed_runs(<checkout>/data/runs)",
        )  # fmt: skip
    return {name: partial(read_run, folder / name) for name in SEED_RUNS}


class TuningView:
    """The panel's figure: built once, then `show` moves its artists (never adds axes).

    Left, the seed's Figure 2: estimated path (red) and true path (grey), estimated landmarks
    (red circles) with 95% ellipses (blue), true tags (green), true start (blue dot). Right, the
    NIS νᵀS⁻¹ν of each update over time (eqs. 13-15) on a log scale, with the gate and the
    χ²(2) mean 2 that a consistent filter averages. Title: the Table 1 row and the average NIS.

    Drawing is most of an update's time, so the figure avoids what costs without showing
    anything: no layout engine, and the NIS axis plots log10(NIS) on a linear axis with plain
    decade labels (a log-scale axis transforms every point and typesets every label each draw).
    """

    def __init__(self, figure: Figure) -> None:
        self.figure = fig = figure
        # A fixed layout: constrained layout would re-measure every tick label on every redraw
        # (about half the drawing time here), and the boxes must not move while a slider does.
        fig.set_layout_engine("none")
        fig.subplots_adjust(left=0.09, right=0.985, bottom=0.09, top=0.86, wspace=0.22)
        self.map_ax, self.nis_ax = fig.subplots(1, 2, width_ratios=(1.45, 1))
        ax = self.map_ax
        (self.true_path,) = ax.plot([], [], "--", color="0.55", lw=1, label="true path")
        (self.path,) = ax.plot([], [], "-", color="tab:red", lw=1.2, label="estimated path")
        (self.true_tags,) = ax.plot([], [], "o", color="tab:green", ms=8, label="true tags")
        self.tags = ax.scatter(
            np.empty(0),
            np.empty(0),
            s=90,
            facecolors="none",
            edgecolors="tab:red",
            linewidths=1.5,
            label="estimated tags",
        )
        (self.start,) = ax.plot([], [], "o", color="tab:blue", ms=7, label="true start")
        ax.plot([], [], "-", color="tab:blue", label="95% ellipses")
        self.ellipses: list[Ellipse] = []
        ax.set_aspect("equal", adjustable="box")
        ax.locator_params(nbins=5)  # every tick label is typeset again on every redraw
        ax.set(xlabel="x (m)", ylabel="y (m)", title="map and path (Figure 2)")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7, framealpha=0.8)
        n = self.nis_ax
        (self.accepted,) = n.plot([], [], ".", color="tab:blue", ms=3, label="accepted")
        (self.rejected,) = n.plot([], [], "x", color="tab:red", ms=4, label="rejected by gate")
        self.gate_line = n.axhline(math.log10(CHI2_2DOF_99), color="tab:red", lw=1, label="gate")
        n.axhline(math.log10(2.0), color="k", ls="--", lw=1, label="χ²(2) mean = 2")
        n.set(xlabel="time (s)", ylabel="NIS (log scale)", title="NIS of each update (eqs. 13-15)")
        n.grid(True, alpha=0.3)
        n.legend(loc="upper right", fontsize=7, framealpha=0.8)
        self.text = fig.suptitle("", family="monospace", fontsize=9.5)
        self._decades = (0, 0)

    def show(self, run: RunLog, result: ReplayResult, summary: RunSummary) -> None:
        """Move every artist to this replay's data (in place; the canvas is not drawn here)."""
        h = result.history
        self.path.set_data(h.pose[:, 0], h.pose[:, 1])
        gt = run.groundtruth
        gt_xy = gt.pose[:, :2] if gt is not None and len(gt.t) else np.empty((0, 2))
        self.true_path.set_data(gt_xy[:, 0], gt_xy[:, 1])
        self.start.set_data(gt_xy[:1, 0], gt_xy[:1, 1])
        tags = run.meta.tag_map or {}
        truth = np.array([tags[i] for i in sorted(tags)]).reshape(-1, 2)
        self.true_tags.set_data(truth[:, 0], truth[:, 1])
        ids = sorted(result.landmarks)
        est = np.array([result.landmarks[i] for i in ids]).reshape(-1, 2)
        self.tags.set_offsets(est)
        while len(self.ellipses) < len(ids):  # a pool: a run with more landmarks adds patches
            patch = Ellipse((0, 0), 0, 0, fill=False, color="tab:blue", lw=1.2)
            self.ellipses.append(self.map_ax.add_patch(patch))
        for k, patch in enumerate(self.ellipses):
            patch.set_visible(k < len(ids))
            if k < len(ids):
                w, hgt, angle = ellipse_parameters(result.landmark_covariances[ids[k]])
                patch.set(center=tuple(est[k]), width=w, height=hgt, angle=angle)
        self._map_limits(np.vstack([truth, gt_xy]), np.vstack([est, h.pose[:, :2]]))
        self._show_nis(result)
        self.text.set_text("\n".join(status_text(summary).splitlines()[:2]))

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
        self.map_ax.set_xlim(centre[0] - half, centre[0] + half)
        self.map_ax.set_ylim(centre[1] - half, centre[1] + half)

    def _show_nis(self, result: ReplayResult) -> None:
        h = result.history
        for line, outcome in ((self.accepted, Outcome.ACCEPTED), (self.rejected, Outcome.REJECTED)):
            mask = h.outcome_mask(outcome)
            line.set_data(h.obs_t[mask], np.log10(np.maximum(h.obs_nis[mask], NIS_FLOOR)))
        gate = result.config.gate
        self.gate_line.set_visible(gate is not None)
        self.gate_line.set_ydata([math.log10(gate or 1.0)] * 2)
        nis = h.obs_nis[np.isfinite(h.obs_nis)]
        top = max(math.ceil(math.log10(max(float(nis.max()), 1.0))) if len(nis) else 2, 2)
        bottom = round(math.log10(NIS_FLOOR))
        self.nis_ax.set_ylim(bottom - 0.2, top + 0.2)
        if (bottom, top) != self._decades:  # the decade labels change only with the range
            self._decades = (bottom, top)
            step = max(1, math.ceil((top - bottom) / 7))
            ticks = list(range(bottom, top + 1, step))
            self.nis_ax.set_yticks(ticks, [f"{10.0**k:g}" for k in ticks])
        t = h.t if len(h.t) else np.array([0.0, 1.0])
        self.nis_ax.set_xlim(float(t[0]), float(t[-1]) + 1e-9)


def status_text(summary: RunSummary, seed: Row | None = None) -> str:
    """The Table 1 row of a replay (eq. 17), its average NIS and its update counts, 3 lines;
    with `seed` (the seed's real-robot row), that row under ours, 4 lines."""
    nis = "-" if summary.nis_mean is None else f"{summary.nis_mean:.2f}"
    lines = table1_lines(summary, seed, layout=PANEL, extra=("avg NIS", nis))
    counts = (
        f"updates accepted {summary.accepted}, rejected {summary.rejected}, "
        f"initialised {summary.initialised}, refused {summary.refused}"
        + (f", singular S {summary.singular}" if summary.singular else "")
    )
    return "\n".join([*lines, counts])


@dataclass(frozen=True, eq=False)
class TunerState:
    """One finished update: its settings, replay, summary, text and timings (s)."""

    settings: TunerSettings
    result: ReplayResult
    summary: RunSummary
    text: str
    replay_seconds: float
    update_seconds: float


class Tuner:
    """Re-runs the replay for new settings and redraws the view in place, latest value wins.

    Parameters
    ----------
    runs : {name: loader} (see `seed_runs`); each loaded once.
    figure : the Figure to draw on (an ipympl one in the panel; any in tests), default 9x6 in.
    settings : where to start; default the first run with its `default_noise`.
    schedule : how to defer work (see `Coalescer`); default: the kernel's loop, or at once.
    raise_errors : re-raise exceptions from an update (tests); otherwise they go to `on_error`.
    on_update, on_error : called with each `TunerState` / exception.
    compute : (run, noise, config) -> (replay, summary); default
        `ekfslam.analysis.evaluation.replay_and_summarize`.
    """

    def __init__(
        self,
        runs: Mapping[str, RunSource],
        figure: Figure | None = None,
        *,
        settings: TunerSettings | None = None,
        schedule=None,
        raise_errors: bool = True,
        on_update: Callable[[TunerState], None] | None = None,
        on_error: Callable[[BaseException], None] | None = None,
        compute: Compute = replay_and_summarize,
    ) -> None:
        if not runs:
            raise ValueError("a Tuner needs at least one run")
        self.runs = dict(runs)
        self._loaded: dict[str, RunLog] = {}
        if settings is None:
            first = next(iter(self.runs))
            settings = TunerSettings(first, default_noise(self.load(first)))
        self.settings = settings
        self.view = TuningView(figure if figure is not None else Figure(figsize=DEFAULT_FIGSIZE))
        self.raise_errors, self.on_update, self.on_error = raise_errors, on_update, on_error
        self.compute = compute
        self.state: TunerState | None = None
        self.last_error: BaseException | None = None
        self._renders = self._changes = 0
        self._coalescer = Coalescer(self._render, schedule)

    @property
    def figure(self) -> Figure:
        return self.view.figure

    @property
    def renders(self) -> int:
        """How many replays have run (a request superseded before it ran never does)."""
        return self._renders

    @property
    def changes(self) -> int:
        """How many changes `set` has received (each slider value is one)."""
        return self._changes

    def load(self, name: str) -> RunLog:
        """The run called `name`, loaded on first use."""
        if name not in self.runs:
            raise ValueError(f"unknown run {name!r}; choose from {sorted(self.runs)}")
        if name not in self._loaded:
            self._loaded[name] = self.runs[name]()
        return self._loaded[name]

    def set(self, **changes: object) -> None:
        """Change settings (names as in `apply_changes`) and schedule a re-run: the widgets' way."""
        self._guard(self._set, changes)

    def refresh(self) -> None:
        """Schedule a re-run with the current settings."""
        self._coalescer.request(self.settings)

    def apply(self, **changes: object) -> TunerState:
        """Change settings and re-run now, raising any error: for code cells and tests."""
        self.settings = apply_changes(self.settings, changes)
        self._coalescer.cancel()
        self._render_now(self.settings)
        return self.state

    def _set(self, changes: Mapping[str, object]) -> None:
        self._changes += 1
        self.settings = apply_changes(self.settings, changes)
        self._coalescer.request(self.settings)

    def _render(self, settings: TunerSettings) -> None:
        self._guard(self._render_now, settings)

    def _render_now(self, settings: TunerSettings) -> None:
        started = time.perf_counter()
        run = self.load(settings.run)
        result, summary = self.compute(run, settings.noise, settings.config)
        self.view.show(run, result, summary)
        self.figure.canvas.draw_idle()
        self.last_error = None
        self._renders += 1
        self.state = TunerState(
            settings,
            result,
            summary,
            status_text(summary),
            result.seconds,  # the replay loop's own time
            time.perf_counter() - started,
        )
        if self.on_update is not None:
            self.on_update(self.state)

    def _guard(self, fn: Callable, arg: object) -> None:
        try:
            fn(arg)
        except Exception as exc:
            self.last_error = exc
            if self.on_error is not None:
                self.on_error(exc)
            if self.raise_errors or self.on_error is None:
                raise
