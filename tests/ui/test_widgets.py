"""The live tuning panel's callback logic, without a browser (tests/integration/test_browser.py has
one)."""

from __future__ import annotations

import asyncio
import base64
import re
import struct
import time
from dataclasses import replace

import numpy as np
import pytest
from matplotlib.backend_bases import FigureCanvasBase
from matplotlib.figure import Figure

from ekfslam.analysis.alignment import align
from ekfslam.core.filter.history import Outcome
from ekfslam.core.noise import NoiseConfig
from ekfslam.errors import InputError
from ekfslam.logs.mrclam.defaults import MRCLAM_NOISE
from ekfslam.logs.runlog import Detections, GroundTruth, RunLog, read_run
from ekfslam.ui.coalescer import Coalescer
from ekfslam.ui.tuning import (
    GATES,
    RUNS_DIR,
    SLIDERS,
    Tuner,
    TunerSettings,
    apply_changes,
    seed_runs,
)
from ekfslam.ui.view import status_text
from ekfslam.ui.widgets import STATIC_CLASS, STATIC_CSS, STATUS_DELAY, tuning_panel

CHI2_95 = 5.991464547107979  # chi-square(2) 95% quantile: the radius² of a 95% ellipse
CHI2_99 = 9.21034037197618  # and 99%: the default gate


def prefix(run: RunLog, seconds: float) -> RunLog:
    """The first `seconds` of a run (keeps the tests fast; the filter sees a shorter log)."""
    c, d, g = run.controls, run.detections, run.groundtruth
    keep_c, keep_d, keep_g = c.t <= seconds, d.t <= seconds, g.t <= seconds
    return replace(
        run,
        controls=replace(c, t=c.t[keep_c], values=c.values[keep_c]),
        detections=Detections(d.t[keep_d], d.tag_id[keep_d], d.range[keep_d], d.bearing[keep_d]),
        groundtruth=GroundTruth(g.t[keep_g], g.pose[keep_g]),
    )


@pytest.fixture(scope="module")
def square() -> RunLog:
    return prefix(read_run(RUNS_DIR / "square-2laps"), 30.0)


@pytest.fixture(scope="module")
def octagon() -> RunLog:
    return prefix(read_run(RUNS_DIR / "octagon-2laps"), 30.0)


class Manual:
    """A scheduler that only collects callbacks: the test decides when 'later' is."""

    def __init__(self) -> None:
        self.calls: list = []

    def __call__(self, fn) -> None:
        self.calls.append(fn)

    def run(self) -> None:
        calls, self.calls = self.calls, []
        for fn in calls:
            fn()


class CountingCanvas(FigureCanvasBase):
    """Draws nothing (fast tests) but counts the redraw requests."""

    idle_draws = 0

    def draw_idle(self, *args, **kwargs) -> None:
        self.idle_draws += 1


def make_tuner(square, octagon, **kwargs) -> Tuner:
    fig = Figure(figsize=(9, 6))
    CountingCanvas(fig)
    runs = {"square": lambda: square, "octagon": lambda: octagon}
    return Tuner(runs, fig, **kwargs)


# --------------------------------------------------------------------- widget values -> configs
def test_slider_values_become_noise_and_filter_configs():
    s = TunerSettings("square")
    new = apply_changes(
        s, {"sigma_range": 0.2, "sigma_bearing": 0.004, "sigma_theta": 0.5, "gate": GATES["off"]}
    )
    assert (new.noise.sigma_range, new.noise.sigma_bearing) == (0.2, 0.004)
    assert new.noise.sigma_theta == 0.5 and new.noise.sigma_x == s.noise.sigma_x
    np.testing.assert_allclose(new.noise.Q, np.diag([0.2**2, 0.004**2]))  # eq. (11)
    assert new.config.gate is None  # "off" is 0, as on the command line
    new = apply_changes(new, {"gate": GATES["95% (5.99)"], "init": "seed", "run": "octagon"})
    assert new.config.gate == pytest.approx(CHI2_95) and new.config.init == "seed"
    assert new.run == "octagon" and new.noise.sigma_range == 0.2  # the rest is kept
    with pytest.raises(ValueError, match="unknown setting"):
        apply_changes(s, {"sigma_q": 1.0})
    with pytest.raises(ValueError):
        apply_changes(s, {"init": "magic"})


def test_log_sliders_cover_the_documented_noise_and_step_by_a_factor(square):
    for noise in (NoiseConfig(), MRCLAM_NOISE):
        for spec in SLIDERS:
            assert 10**spec.lo < getattr(noise, spec.field) < 10**spec.hi, spec.field
    panel = tuning_panel({"square": lambda: square}, figure=Figure())
    for spec in SLIDERS:
        slider, value = panel.sliders[spec.field], getattr(NoiseConfig(), spec.field)
        assert slider.base == 10 and slider.step == spec.step
        assert slider.value == value  # exactly the documented noise ...
        k = (np.log10(value) - slider.min) / slider.step
        assert k == pytest.approx(round(k), abs=1e-9)  # ... on the grid, so nothing snaps
        assert slider.min <= spec.lo < spec.lo + spec.step and slider.max >= spec.hi
    # a keyboard step moves the exponent by `step`: the noise grows by 10**0.1 ≈ 1.259
    slider = panel.sliders["sigma_range"]
    slider.value = 10 ** (np.log10(slider.value) + slider.step)
    assert panel.tuner.settings.noise.sigma_range == pytest.approx(0.03 * 1.2589, rel=1e-4)
    assert panel.tuner.state.settings.noise.sigma_range == slider.value  # and it re-ran
    renders = panel.tuner.renders
    slider.value = slider.value * (1 + 1e-15)  # a browser echoing the value back
    assert panel.tuner.renders == renders


def test_values_set_from_code_land_exactly_on_the_sliders(square):
    panel = tuning_panel({"square": lambda: square}, figure=Figure())
    state = panel.apply(sigma_range=0.0123, sigma_theta=0.5, gate=0)
    for name, value in (("sigma_range", 0.0123), ("sigma_theta", 0.5)):
        slider = panel.sliders[name]
        assert slider.value == value == getattr(state.settings.noise, name)
        k = (np.log10(value) - slider.min) / slider.step
        assert k == pytest.approx(round(k), abs=1e-9)
    assert panel.gate.value == 0.0 and state.settings.config.gate is None


# -------------------------------------------------------------------------- drawing in place
def test_update_moves_the_same_artists_to_the_new_replay(square, octagon):
    tuner = make_tuner(square, octagon)
    first = tuner.apply(sigma_range=0.01, sigma_bearing=0.01)
    view = tuner.view
    artists = (view.path, view.tags, view.true_tags, view.accepted, view.text, *view.ellipses)
    axes = list(tuner.figure.axes)
    xy_before = np.column_stack(view.path.get_data())
    widths_before = [e.width for e in view.ellipses]
    second = tuner.apply(sigma_range=0.1, sigma_bearing=0.1)
    assert tuner.figure.axes == axes  # nothing rebuilt ...
    assert (view.path, view.tags, view.true_tags, view.accepted, view.text, *view.ellipses) == (
        artists
    )
    # ... but every artist shows the new replay
    xy = np.column_stack(view.path.get_data())
    np.testing.assert_array_equal(xy, second.result.history.pose[:, :2])
    assert not np.allclose(xy, xy_before)
    ids = sorted(second.result.landmarks)
    np.testing.assert_array_equal(
        view.tags.get_offsets(), [second.result.landmarks[i] for i in ids]
    )
    for patch, i in zip(view.ellipses, ids, strict=True):
        lam = np.linalg.eigvalsh(second.result.landmark_covariances[i])
        assert patch.width == pytest.approx(2 * np.sqrt(CHI2_95 * lam[1]), rel=1e-9)
        assert patch.height == pytest.approx(2 * np.sqrt(CHI2_95 * lam[0]), rel=1e-9)
        assert patch.center == pytest.approx(second.result.landmarks[i])
    # ten times the observation noise: the map is less certain, the ellipses larger
    assert np.mean([e.width for e in view.ellipses]) > 1.5 * np.mean(widths_before)
    assert first.text != second.text


def test_the_ellipse_pool_follows_the_number_of_landmarks(square, octagon):
    d = square.detections
    few = d.tag_id < 3  # only three tags ever seen
    three = replace(
        square, detections=Detections(d.t[few], d.tag_id[few], d.range[few], d.bearing[few])
    )
    tuner = make_tuner(three, square)
    tuner.apply(run="octagon")
    pool = list(tuner.view.ellipses)
    assert sum(e.get_visible() for e in pool) == len(tuner.state.result.landmarks) == 8
    tuner.apply(run="square")
    assert tuner.view.ellipses == pool  # reused, not replaced
    assert [e.get_visible() for e in pool] == [True] * 3 + [False] * 5
    assert len(tuner.view.tags.get_offsets()) == 3


def test_text_shows_the_table1_row_and_the_average_nis(square, octagon):
    tuner = make_tuner(square, octagon)
    state = tuner.apply()
    result = state.result
    a = align(result.landmarks, square.meta.tag_map)  # eq. (17), computed here independently
    h = result.history
    nis = h.obs_nis[h.obs_outcome == Outcome.ACCEPTED].mean()
    row = state.text.splitlines()[1].split()
    assert row[0] == "square-2laps"
    np.testing.assert_allclose(
        [float(v) for v in row[1:6]], [a.x0, a.y0, a.theta0, a.mean_error, nis], atol=6e-3
    )
    counts = dict(re.findall(r"(\w+) (\d+)", state.text.splitlines()[2]))
    assert int(counts["accepted"]) == int(np.sum(h.obs_outcome == Outcome.ACCEPTED))
    shown = [tuner.view.header.get_text(), tuner.view.text.get_text()]
    assert shown == state.text.splitlines()[:2]


def test_too_small_q_gets_updates_rejected_and_shows_them(square, octagon):
    tuner = make_tuner(square, octagon)
    fine = tuner.apply()
    assert fine.summary.rejected == 0
    assert len(tuner.view.rejected.get_xdata()) == 0
    tight = tuner.apply(sigma_range=0.001, sigma_bearing=0.001)  # far below the sim's 0.02
    assert tight.summary.rejected > 10
    assert tight.summary.nis_mean > 2 * fine.summary.nis_mean  # overconfident
    assert len(tuner.view.rejected.get_xdata()) == tight.summary.rejected
    h_tight = tight.result.history
    nis_rejected = h_tight.obs_nis[h_tight.obs_outcome == Outcome.REJECTED]
    assert np.all(nis_rejected > tight.settings.config.gate)  # the gate did what it says
    np.testing.assert_allclose(tuner.view.rejected.get_ydata(), np.log10(nis_rejected))
    assert tuner.view.gate_line.get_ydata()[0] == pytest.approx(np.log10(CHI2_99))
    labels = [t.get_text() for t in tuner.view.nis_ax.get_yticklabels()]
    assert labels[:5] == ["0.01", "0.1", "1", "10", "100"]  # decades, in plain numbers
    tuner.apply(gate=0)
    assert not tuner.view.gate_line.get_visible() and tuner.state.summary.rejected == 0


def test_status_text_without_a_tag_map(square, octagon):
    blind = replace(square, meta=replace(square.meta, tag_map=None))
    state = make_tuner(blind, octagon).apply()
    assert "no alignment" in state.text
    assert status_text(state.summary) == state.text


# ------------------------------------------------------------------------ latest value wins
def test_rapid_changes_run_once_with_the_latest_value(square, octagon):
    later = Manual()
    tuner = make_tuner(square, octagon, schedule=later)
    for sigma in np.geomspace(0.01, 0.2, 12):
        tuner.set(sigma_range=sigma)
    assert tuner.renders == 0 and len(later.calls) == 1  # one run scheduled, nothing queued
    assert tuner.changes == 12
    later.run()
    assert tuner.renders == 1 and tuner.figure.canvas.idle_draws == 1
    assert tuner.state.settings.noise.sigma_range == pytest.approx(0.2)
    later.run()
    assert tuner.renders == 1  # nothing stale left to do


def test_a_change_during_a_run_is_run_next():
    later, done = Manual(), []

    def work(value):
        done.append(value)
        if value == 1:
            coalescer.request(2)  # arrives while 1 is being worked on

    coalescer = Coalescer(work, later)
    coalescer.request(1)
    later.run()
    later.run()
    assert done == [1, 2]


def test_on_the_kernel_loop_values_queued_during_a_run_collapse():
    """As in a kernel: each value is a loop callback; the work blocks the loop 50 ms."""
    done = []

    def work(value):
        done.append(value)
        time.sleep(0.05)

    async def main():
        coalescer = Coalescer(work)  # the default: the running loop, COALESCE_DELAY later
        loop = asyncio.get_running_loop()
        for k in range(20):  # a drag: a new value every 5 ms for 0.1 s
            loop.call_later(0.005 * k, coalescer.request, k)
        await asyncio.sleep(0.5)

    asyncio.run(main())
    assert done[-1] == 19
    assert len(done) <= 4  # a callback per value would have blocked for 20 x 50 ms


def test_on_the_kernel_loop_the_text_follows_the_frame_and_shows_the_latest_state(square):
    """In a kernel the text under the figure waits STATUS_DELAY after the frame; `apply`
    (code cells) and errors show at once, and an error is never covered by an older state."""
    panel = tuning_panel({"square": lambda: square}, figure=Figure())

    async def main():
        shown = panel.status.value
        panel.tuner.apply(sigma_range=0.02)  # a slider's path: the tuner, then on_update
        panel.tuner.apply(sigma_range=0.05)
        assert panel.status.value == shown  # not yet: the frame goes first
        await asyncio.sleep(STATUS_DELAY + 0.1)
        latest = panel.status.value
        assert latest != shown and f"{panel.tuner.renders} replays" in latest
        panel.apply(sigma_range=0.03)  # a code cell: at once
        assert panel.status.value != latest
        panel.tuner.apply(sigma_range=0.04)  # waiting ...
        panel.tuner.raise_errors = False
        panel.tuner.set(gate=-1.0)  # ... when an error comes
        await asyncio.sleep(STATUS_DELAY + 0.1)
        assert "error:" in panel.status.value

    asyncio.run(main())


# --------------------------------------------------------------------------- errors surface
def test_errors_are_raised_by_a_bare_tuner(square, octagon, tmp_path):
    tuner = make_tuner(square, octagon)
    tuner.runs["broken"] = lambda: read_run(tmp_path / "missing")
    with pytest.raises(InputError, match="missing"):
        tuner.set(run="broken")
    with pytest.raises(ValueError, match="gate"):
        tuner.set(gate=-1.0)


def test_the_panel_shows_errors_and_keeps_the_last_figure(square, tmp_path):
    runs = {"square": lambda: square, "broken": lambda: read_run(tmp_path / "missing")}
    panel = tuning_panel(runs, figure=Figure())
    path = np.column_stack(panel.tuner.view.path.get_data())
    panel.run.value = "broken"  # what a student's click does; must not raise into ipywidgets
    assert isinstance(panel.tuner.last_error, InputError)
    assert "error:" in panel.status.value and "missing" in panel.status.value
    shown = "".join(o.get("text", "") for o in panel.errors.outputs)
    assert "InputError" in shown and "Traceback" in shown
    np.testing.assert_array_equal(np.column_stack(panel.tuner.view.path.get_data()), path)
    panel.run.value = "square"  # a good setting clears the error
    assert panel.tuner.last_error is None and panel.errors.outputs == ()
    assert "square-2laps" in panel.status.value


def test_reset_restores_the_runs_documented_noise(square):
    panel = tuning_panel({"square": lambda: square}, figure=Figure())
    panel.apply(sigma_x=0.3, sigma_bearing=0.5)
    assert panel.sliders["sigma_x"].value == pytest.approx(0.3)
    panel.reset.click()
    for spec in SLIDERS:
        default = getattr(NoiseConfig(), spec.field)
        assert panel.sliders[spec.field].value == pytest.approx(default)
        assert getattr(panel.tuner.state.settings.noise, spec.field) == pytest.approx(default)


def test_seed_runs_are_the_shipped_two(tmp_path):
    assert set(seed_runs()) == {"square-2laps", "octagon-2laps"}
    with pytest.raises(InputError, match="not found"):
        seed_runs(tmp_path / "nowhere")


def test_the_static_fallback_is_the_current_figure_as_a_png_and_the_table1_text(square):
    panel = tuning_panel({"square": lambda: square}, figure=Figure(figsize=(9, 6), dpi=100))
    page = panel.static_html()
    match = re.search(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)"', page)
    assert match, page[:300]
    png = base64.b64decode(match.group(1))
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", png[16:24])  # the IHDR chunk
    assert (width, height) == (900, 600)
    table = re.search(r'<pre class="ekfslam-table1"[^>]*>(.*?)</pre>', panel.status.value, re.S)
    assert table.group(1) in page and "square-2laps" in page
    assert "ekfslam-table1" not in page  # the browser tests' selectors find the live one only
    # hidden only next to a live ipympl canvas, inside the same output area
    assert f'<div class="{STATIC_CLASS}"><style>{STATIC_CSS}</style>' in page
    assert ":has(.jupyter-matplotlib-canvas-div)" in STATIC_CSS
    before = page
    panel.apply(sigma_range=0.005)  # the fallback shows the figure as it is now
    assert panel.static_html() != before


def test_a_value_typed_into_a_sliders_box_is_kept_exactly(square):
    """Regression: typing 0.005 into the σr readout gave 0.00475, the browser's slider snapping
    it to its grid (a tenth of a decade from 0.03). The box beside each slider sends what was
    typed; the slider's grid is re-anchored on it and the replay runs with it."""
    panel = tuning_panel({"square": lambda: square}, figure=Figure())
    box, slider = panel.boxes["sigma_range"], panel.sliders["sigma_range"]
    assert slider.readout is False and box.value == slider.value == 0.03
    box.value = 0.005  # what the browser sends for "0.005" typed into the box
    assert slider.value == 0.005 and panel.tuner.settings.noise.sigma_range == 0.005
    assert panel.tuner.state.settings.noise.sigma_range == 0.005  # it re-ran with it
    k = (np.log10(0.005) - slider.min) / slider.step
    assert k == pytest.approx(round(k), abs=1e-9)  # on the slider's grid: no snap either way
    slider.value = 10 ** (np.log10(0.005) + slider.step)  # a key press on the slider
    assert box.value == slider.value and panel.tuner.settings.noise.sigma_range == box.value
    panel.apply(sigma_range=0.02)
    assert box.value == slider.value == 0.02
