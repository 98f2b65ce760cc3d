"""The live tuning panel: log-scale R and Q sliders that re-run the replay and redraw in place.

The panel is the ipywidgets + ipympl face of an `ekfslam.ui.tuning.Tuner`; the settings, the
coalescing of rapid changes, the figure updates and their tests live there. For a classroom
projector serve the notebook as an app: ``voila notebooks/08-live-tuning.ipynb``.
"""

from __future__ import annotations

import asyncio
import base64
import html
import io
import math
import traceback
from collections.abc import Mapping
from functools import partial

from IPython.display import HTML, display  # (ipywidgets needs IPython: no extra dependency)
from matplotlib.figure import Figure

from ekfslam.analysis.evaluation import SEED_TABLE1, seed_experiment
from ekfslam.core.noise import default_noise
from ekfslam.ui.coalescer import Coalescer
from ekfslam.ui.tuning import (
    DEFAULT_FIGSIZE,
    GATES,
    SLIDERS,
    SPECS,
    RunSource,
    Tuner,
    TunerSettings,
    TunerState,
    seed_runs,
)
from ekfslam.ui.view import status_text

#: The static fallback's class, and the rule that hides it next to a live ipympl canvas (the
#: output areas of JupyterLab and Voila, ``.jp-OutputArea``, and of the classic notebook).
STATIC_CLASS = "ekfslam-static"
STATIC_CSS = (
    ":is(.jp-OutputArea,.output):has(.jupyter-matplotlib-canvas-div) "
    f".{STATIC_CLASS}{{display:none}}"
)

TABLE_STYLE = "font:15px monospace;margin:4px 0"

#: Seconds the text under the figure waits after a move's frame. Sent at once, it reached the
#: browser together with the frame, whose bytes the browser still had to load and decode, and
#: its layout went first: measured in Voila, alternately in one run at load 8, a key press to
#: new pixels took 73.5 ms median with the text at once and 61.1 ms with it 50 ms later. The
#: figure shows the same Table 1 row at once; the text under it is the copy to read and copy.
STATUS_DELAY = 0.05


def after_the_frame(fn) -> None:
    """Call `fn` `STATUS_DELAY` s from now on the running asyncio loop (the kernel's), or at
    once where there is none (tests, scripts)."""
    try:
        loop = asyncio.get_running_loop()
    except RuntimeError:
        fn()
    else:
        loop.call_later(STATUS_DELAY, fn)


class TuningPanel:
    """The ipywidgets + ipympl face of a `Tuner` (build it with `tuning_panel`).

    Attributes: `tuner`; `sliders` {NoiseConfig field: FloatLogSlider}; `run`, `init`, `gate`
    pickers; `reset` (the run's documented noise); `status` (HTML: the Table 1 row);
    `errors` (Output: tracebacks of failed updates); `widget`, the whole panel.
    """

    def __init__(self, tuner: Tuner) -> None:
        import ipywidgets as w  # lazy: a notebook-only dependency; the tuner itself runs without

        self.tuner, s = tuner, tuner.settings
        tuner.raise_errors, tuner.on_update, tuner.on_error = False, self._updated, self._failed
        self._quiet, self._table = False, ""
        self._status = Coalescer(self._show_status, after_the_frame)  # the latest state only
        wide = {"description_width": "110px"}
        self.sliders = {
            spec.field: w.FloatLogSlider(
                value=getattr(s.noise, spec.field),
                base=10,
                min=spec.grid(getattr(s.noise, spec.field))[0],
                max=spec.grid(getattr(s.noise, spec.field))[1],
                step=spec.step,
                description=f"{spec.label} ({spec.unit})",
                readout=False,  # the box beside it: a value typed there is kept, not snapped
                style=wide,
                layout=w.Layout(width="400px"),
            )
            for spec in SLIDERS
        }
        # A slider's own readout, typed into, is snapped by the browser to the slider's grid
        # before the kernel sees it (0.005 became 0.00475); a text box sends what was typed,
        # and the slider's grid is re-anchored on it (`_show_values`), so nothing snaps.
        self.boxes = {
            spec.field: w.BoundedFloatText(
                value=getattr(s.noise, spec.field),
                min=10**spec.lo,
                max=10**spec.hi,
                step=None,
                layout=w.Layout(width="90px"),
            )
            for spec in SLIDERS
        }
        for field, box in self.boxes.items():
            box.add_class(f"ekfslam-value-{field}")
        gates = dict(GATES)
        if (s.config.gate or 0.0) not in gates.values():
            gates[f"{s.config.gate:.3g}"] = s.config.gate
        self.run = w.Dropdown(options=list(tuner.runs), value=s.run, description="run", style=wide)
        self.init = w.Dropdown(
            options=[("inverse, eq. (12)", "inverse"), ("seed, eq. (3)", "seed")],
            value=s.config.init,
            description="landmark init",
            style=wide,
        )
        self.gate = w.Dropdown(
            options=list(gates.items()),
            value=s.config.gate or 0.0,
            description="NIS gate (χ²)",
            style=wide,
        )
        self.reset = w.Button(description="reset R and Q", icon="undo")
        self.fit = w.Button(
            description="fit R and Q",
            icon="magic",
            tooltip="maximum likelihood of the innovations: no ground truth (10-60 s on MRCLAM)",
        )
        self.status, self.errors = w.HTML(), w.Output()
        for name, box in self.boxes.items():
            box.observe(partial(self._typed, name), names="value")
        for name, widget in (
            *self.sliders.items(),
            ("run", self.run),
            ("init", self.init),
            ("gate", self.gate),
        ):
            widget.observe(partial(self._changed, name), names="value")
        self.reset.on_click(self._reset)
        self.fit.on_click(self._fit)
        canvas = tuner.figure.canvas
        if isinstance(canvas, w.DOMWidget):  # ipympl: the figure is itself a widget
            canvas.header_visible = False
            canvas.toolbar_position = "right"
        else:  # any other backend (tests): the controls still work, without a picture
            canvas = w.HTML("<i>(the figure needs <code>%matplotlib widget</code>)</i>")
        pickers = w.VBox([self.run, self.init, self.gate, self.reset, self.fit])
        rows = [w.HBox([self.sliders[n], self.boxes[n]]) for n in self.sliders]
        controls = w.VBox([w.HBox([w.VBox(rows), pickers]), self.status])
        # the controls beside the figure where the page is wide enough (Voila at 1920 x 1080:
        # the whole figure on the screen with the sliders), above it where it is not
        wrap = w.Layout(display="flex", flex_flow="row wrap", align_items="flex-start")
        self.widget = w.VBox([w.Box([controls, canvas], layout=wrap), self.errors])
        if tuner.state is not None:
            self._show_status(tuner.state)

    def apply(self, **changes: object) -> TunerState:
        """Set widgets and settings together and re-run now (for code cells and checks); the
        text under the figure is updated before this returns."""
        self._show_values(changes)
        state = self.tuner.apply(**changes)
        self._follow_noise()
        self._status.flush()
        return state

    def _ipython_display_(self) -> None:
        """Show the live widget and, after it, `static_html` (the fallback for a static export).

        A frontend that renders the widget hides the fallback by CSS (`STATIC_CSS`): the rule
        matches only an output area that holds a live ipympl canvas, which a notebook exported to
        HTML (``jupyter nbconvert --execute --to html``) never has, so there the PNG shows.
        """
        display(self.widget)
        display(HTML(self.static_html()))

    def static_html(self) -> str:
        """The figure as it is now as a base64 PNG, and the Table 1 text, for a page without
        a kernel (`STATIC_CSS` hides it where the live figure is shown)."""
        buf = io.BytesIO()
        self.tuner.figure.savefig(buf, format="png", dpi="figure")
        png = base64.b64encode(buf.getvalue()).decode("ascii")
        return (
            f'<div class="{STATIC_CLASS}"><style>{STATIC_CSS}</style>'
            f'<img src="data:image/png;base64,{png}" alt="the tuning panel\'s figure"'
            ' style="max-width:100%"/>'
            f'<pre style="{TABLE_STYLE}">{self._table}</pre></div>'
        )

    def _typed(self, name: str, change: dict) -> None:
        """A value typed into a slider's box: the slider re-anchored on it, and the replay."""
        if self._quiet:
            return
        self._show_values({name: change["new"]})
        self.tuner.set(**{name: change["new"]})

    def _changed(self, name: str, change: dict) -> None:
        if self._quiet:
            return
        if name in self.sliders:  # the browser may echo a value back with its last bit changed
            if math.isclose(change["new"], getattr(self.tuner.settings.noise, name), rel_tol=1e-9):
                return
            if math.isclose(change["new"], self.boxes[name].value, rel_tol=1e-9):
                return  # the echo of a value typed in the box, before the tuner took it
            self._quiet = True  # the slider moved: its box follows
            try:
                self.boxes[name].value = change["new"]
            finally:
                self._quiet = False
        self.tuner.set(**{name: change["new"]})
        if name == "run":  # a run with other documented noise brings its own R and Q
            self._follow_noise()

    def _follow_noise(self) -> None:
        """The sliders to the tuner's R and Q (they change with the run: `Tuner.set`)."""
        noise = self.tuner.settings.noise
        shown = {n: self.sliders[n].value for n in self.sliders}
        values = {n: getattr(noise, n) for n in self.sliders}
        if any(not math.isclose(shown[n], values[n], rel_tol=1e-9) for n in values):
            self._show_values(values)

    def _reset(self, _button: object) -> None:
        try:
            noise = default_noise(self.tuner.load(self.tuner.settings.run))
        except Exception as exc:
            self._failed(exc)
            return
        values = {spec.field: getattr(noise, spec.field) for spec in SLIDERS}
        self._show_values(values)
        self.tuner.set(**values)

    def _fit(self, _button: object) -> None:
        self.status.value = (
            f'<pre style="{TABLE_STYLE}">fitting R and Q to the innovations...</pre>'
        )
        try:
            self.tuner.fit()
        except Exception as exc:
            self._failed(exc)
            return
        self._follow_noise()
        self._status.flush()

    def _show_values(self, values: Mapping[str, object]) -> None:
        self._quiet = True  # the widgets follow; their observers must not re-run the replay
        try:
            for name, value in values.items():
                if name in self.sliders:
                    slider, spec = self.sliders[name], SPECS[name]
                    with slider.hold_sync():  # re-anchor the grid: the value must not snap
                        lo, hi = spec.grid(value)
                        slider.min, slider.max = min(lo, slider.min), max(hi, slider.max)
                        slider.value = value
                        slider.min, slider.max = lo, hi
                    self.boxes[name].value = value
                elif name in ("run", "init", "gate"):
                    getattr(self, name).value = 0.0 if name == "gate" and value is None else value
        finally:
            self._quiet = False

    def _updated(self, state: TunerState) -> None:
        self._status.request(state)  # after the frame: `STATUS_DELAY`

    def _show_status(self, state: TunerState) -> None:
        self.errors.outputs = ()  # (clear_output needs a kernel; this works everywhere)
        # the seed's real-robot row under ours when the run is the seed's experiment, judged
        # by its simulation config as on the command line, not by its name
        trajectory = seed_experiment(self.tuner.load(state.settings.run).meta.simulation)
        seed = None if trajectory is None else SEED_TABLE1[trajectory]
        self._table = html.escape(status_text(state.summary, seed))
        self.status.value = (
            f'<pre class="ekfslam-table1" style="{TABLE_STYLE}">{self._table}</pre>'
            + diagnosis_html(state)
            + '<div class="ekfslam-timing" style="color:#666">'
            f"replay {state.replay_seconds * 1e3:.0f} ms, "
            f"with the figure update {state.update_seconds * 1e3:.0f} ms; "
            f"{self.tuner.renders} replays for {self.tuner.changes} changes so far</div>"
        )

    def _failed(self, exc: BaseException) -> None:
        self._status.cancel()  # a good state still waiting must not cover the error
        self.status.value = (
            f'<pre class="ekfslam-error" style="color:#b00">'
            f"error: {html.escape(str(exc))} (the figure shows the last good "
            f"setting)</pre>"
        )
        self.errors.append_stderr("".join(traceback.format_exception(exc)))


def diagnosis_html(state: TunerState) -> str:
    """The replay's self-diagnosis under the table: green when ok, red with what it saw and
    what to try when not (`ekfslam.core.diagnosis`)."""
    d = state.summary.diagnosis
    if d is None:
        return ""
    colour = "#070" if d.ok else "#b00"
    text = (
        d.line()
        if d.ok
        else f"diagnosis: {d.warning()}".replace("try --noise fit", "try 'fit R and Q'")
    )
    style = f"color:{colour};font:14px monospace"
    return f'<div class="ekfslam-diagnosis" style="{style}">{html.escape(text)}</div>'


def tuning_panel(
    runs: Mapping[str, RunSource] | None = None,
    *,
    settings: TunerSettings | None = None,
    figure: Figure | None = None,
    blit: bool | None = None,
) -> TuningPanel:
    """The live tuning panel over `runs` (default: the seed runs), drawn once before returning.

    Use after ``%matplotlib widget``; the figure is then an ipympl canvas (9x6.6 in), on which a
    move redraws only the data (`blit`, see `ekfslam.ui.blit`; False: a full draw each time).
    """
    if figure is None:
        import matplotlib.pyplot as plt  # lazy: pyplot picks a backend; only a new figure needs it

        with plt.ioff():  # the panel places the canvas itself
            figure = plt.figure(figsize=DEFAULT_FIGSIZE)
    tuner = Tuner(runs or seed_runs(), figure, settings=settings, blit=blit)
    tuner.apply()
    return TuningPanel(tuner)
