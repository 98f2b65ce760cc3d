"""Live tuning, the logic: R and Q settings that re-run the replay and redraw a figure in place.

Three layers, each ordinary code, tested without a browser:
- `TunerSettings` and `apply_changes`: widget values -> `NoiseConfig` (R of eq. 9, Q of eq. 11)
  and `FilterConfig` (landmark initialisation, NIS gate).
- `TuningView` (`ekfslam.ui.view`): one figure built once (the seed's Figure 2 on the left,
  the NIS of every update on the right, a Table 1 row as its title) whose artists `show`
  updates in place.
- `Tuner`: holds the runs and the current settings, asks its injected compute (by default
  `ekfslam.analysis.evaluation.replay_and_summarize`) for the replay and its score, updates the
  view and redraws it (`TuningView.redraw`: on ipympl only the data, see `ekfslam.ui.blit`);
  changes are coalesced (`ekfslam.ui.coalescer`), so at most one replay runs and one waits.
  `ekfslam.ui.widgets.TuningPanel` is its ipywidgets face.

Errors: an exception in a widget callback is logged by the kernel where no student sees it, so
the panel shows it in an Output widget and keeps the last good figure; a bare `Tuner` re-raises.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path

from matplotlib.figure import Figure

from ekfslam.analysis.evaluation import RunSummary, replay_and_summarize
from ekfslam.analysis.noise_fit import NoiseFit, fit_noise
from ekfslam.core.filter.config import CHI2_2DOF_99, FilterConfig, chi2_2dof_quantile
from ekfslam.core.noise import NoiseConfig, default_noise
from ekfslam.errors import InputError
from ekfslam.logs.mrclam.load import find_dataset, load_mrclam
from ekfslam.logs.runlog import RunLog, read_run
from ekfslam.pipeline import ReplayResult
from ekfslam.ui.coalescer import Coalescer
from ekfslam.ui.view import TuningView, status_text

#: A run to offer in the panel: a function that loads it (called once, then cached).
RunSource = Callable[[], RunLog]
#: What the tuner computes for a setting: the replay and its score (the view only draws them).
Compute = Callable[[RunLog, NoiseConfig, FilterConfig], tuple[ReplayResult, RunSummary]]

#: Where `seed_runs` looks by default: data/runs of the source checkout this package runs from.
#: An installed wheel ships no runs; `seed_runs` then says so and asks for the folder.
RUNS_DIR = Path(__file__).resolve().parents[2] / "data" / "runs"
SEED_RUNS = ("square-2laps", "octagon-2laps")
DEFAULT_FIGSIZE = (9.0, 6.6)
#: NIS gates offered (chi-square, 2 dof); 0 turns gating off, as on the command line.
GATES = {
    "off": 0.0,
    "95% (5.99)": chi2_2dof_quantile(0.95),
    "99% (9.21)": CHI2_2DOF_99,
    "99.9% (13.8)": chi2_2dof_quantile(0.999),
}


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

#: The names `apply_changes` takes as R and Q: the sliders' `NoiseConfig` fields.
NOISE_FIELDS = frozenset(SPECS)


@dataclass(frozen=True)
class TunerSettings:
    """Everything the panel lets a student change: the run's name, R and Q, the filter options."""

    run: str
    noise: NoiseConfig = field(default_factory=NoiseConfig)
    # compiled: a slider's move replays the run, and the panel answers within tens of ms
    config: FilterConfig = field(default_factory=lambda: FilterConfig(backend="numba"))


def apply_changes(settings: TunerSettings, changes: Mapping[str, object]) -> TunerSettings:
    """New settings from widget values: ``run``, a `NoiseConfig` field (a slider's value in its
    units, not its exponent), ``init`` ("inverse" or "seed") or ``gate`` (a NIS threshold; 0 or
    None is off). Raises ValueError for an unknown name or a value the configs refuse."""
    noise = {k: float(v) for k, v in changes.items() if k in NOISE_FIELDS}
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
    Hook for more: any ``{name: loader}`` works, e.g. MRCLAM robots with and without Vicon,
    ``{**seed_runs(), **mrclam_runs((7, 4))}``.
    """
    folder = Path(RUNS_DIR if folder is None else folder)
    if not folder.is_dir():
        raise InputError(
            folder,
            None,
            "run folder not found (an installed ekfslam ships no data/runs); "
            "pass seed_runs(<checkout>/data/runs)",
        )
    return {name: partial(read_run, folder / name) for name in SEED_RUNS}


def mrclam_runs(
    datasets: tuple[int | str | Path, ...] = (7, 1, 4), robots: tuple[int, ...] = (1,)
) -> dict[str, RunSource]:
    """MRCLAM robots for the panel as lazy loaders: ``{"mrclam7-r1": ..., "mrclam1-r1": ...}``.

    datasets : numbers 1-9 (found by `ekfslam.logs.mrclam.load.find_dataset`: the shared data,
    then the download cache) or folders. Each loader reads its robot when the panel first shows
    it, with the MRCLAM defaults (`ekfslam.logs.mrclam.defaults`). Datasets 1 and 4 have no
    Vicon: the panel then draws the estimate after eq. (17) with the start it recovers, and the
    row above the map is the map's score. Raises InputError for a dataset not on this machine.
    """
    runs: dict[str, RunSource] = {}
    for dataset in datasets:
        folder = find_dataset(int(dataset)) if str(dataset).isdigit() else Path(dataset)
        label = folder.name.removeprefix("MRCLAM_Dataset")  # "7" for MRCLAM_Dataset7
        for robot in robots:
            runs[f"mrclam{label}-r{robot}"] = partial(_first, load_mrclam, folder, robot)
    return runs


def _first(load: Callable, *args: object) -> RunLog:
    return load(*args)[0]


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
    figure : the Figure to draw on (an ipympl one in the panel; any in tests), default 9x6.6 in.
    settings : where to start; default the first run with its `default_noise`.
    schedule : how to defer work (see `Coalescer`); default: the kernel's loop, or at once.
    raise_errors : re-raise exceptions from an update (tests); otherwise they go to `on_error`.
    on_update, on_error : called with each `TunerState` / exception.
    compute : (run, noise, config) -> (replay, summary); default
        `ekfslam.analysis.evaluation.replay_and_summarize`.
    blit : redraw only the data (see `TuningView`); default: on a browser's canvas (ipympl).
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
        blit: bool | None = None,
    ) -> None:
        if not runs:
            raise ValueError("a Tuner needs at least one run")
        self.runs = dict(runs)
        self._loaded: dict[str, RunLog] = {}
        self._tuned: dict[NoiseConfig, NoiseConfig] = {}  # a run's defaults -> last noise used
        if settings is None:
            first = next(iter(self.runs))
            settings = TunerSettings(first, default_noise(self.load(first)))
        self.settings = settings
        figure = figure if figure is not None else Figure(figsize=DEFAULT_FIGSIZE)
        self.view = TuningView(figure, blit)
        self.raise_errors, self.on_update, self.on_error = raise_errors, on_update, on_error
        self.compute = compute
        self.state: TunerState | None = None
        self.last_error: BaseException | None = None
        self.last_fit: NoiseFit | None = None  # `fit`'s last result
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
        self.settings = apply_changes(self._run_noise(changes), changes)
        self._coalescer.cancel()
        self._render_now(self.settings)
        return self.state

    def fit(self) -> NoiseFit:
        """Fit R and Q to the current run's innovations (`ekfslam.analysis.noise_fit`, no ground
        truth), starting from the current setting, and re-run with them now; the fit is also
        kept in `last_fit`. A MRCLAM robot takes 10-60 s, a seed run a few."""
        found = fit_noise(self.load(self.settings.run), self.settings.noise, self.settings.config)
        self.last_fit = found
        self.apply(**{name: getattr(found.noise, name) for name in NOISE_FIELDS})
        return found

    def _set(self, changes: Mapping[str, object]) -> None:
        self._changes += 1
        self.settings = apply_changes(self._run_noise(changes), changes)
        self._coalescer.request(self.settings)

    def _run_noise(self, changes: Mapping[str, object]) -> TunerSettings:
        """The settings `changes` apply to: R and Q follow a change to a run with other noise.

        A seed run's σr of 3 cm on a MRCLAM robot (σr 0.3 m) loses the robot: a new run whose
        `default_noise` differs from the old one's starts from the noise last used on runs with
        its defaults (its defaults the first time), and the old run's tuning is kept for the way
        back. Between runs with the same defaults (the seed's square and octagon) R and Q stay,
        so the two compare at one setting. Noise named in `changes` is applied on top.
        """
        run = str(changes.get("run", self.settings.run))
        if run == self.settings.run:
            return self.settings
        old, new = (default_noise(self.load(name)) for name in (self.settings.run, run))
        if old == new:
            return self.settings
        self._tuned[old] = self.settings.noise
        return replace(self.settings, noise=self._tuned.get(new, new))

    def _render(self, settings: TunerSettings) -> None:
        self._guard(self._render_now, settings)

    def _render_now(self, settings: TunerSettings) -> None:
        started = time.perf_counter()
        run = self.load(settings.run)
        result, summary = self.compute(run, settings.noise, settings.config)
        self.view.show(run, result, summary)
        self.view.redraw()
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
