"""Blitting the panel's data: the same picture as a full draw, the background drawn only when
the axes change, and a full draw request while ipympl's view is not live yet."""

from __future__ import annotations

import asyncio
import dataclasses
import io
import math
import time
import zlib

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.backends.backend_webagg_core import FigureCanvasWebAggCore
from matplotlib.figure import Figure
from PIL import Image

from ekfslam.logs.runlog import read_run
from ekfslam.ui import blit
from ekfslam.ui.blit import PNG_COMPRESS_LEVEL, png_bytes, png_from_rows, png_rows, transparent
from ekfslam.ui.coalescer import COALESCE_DELAY, Coalescer
from ekfslam.ui.tuning import DEFAULT_FIGSIZE, RUNS_DIR, Tuner


@pytest.fixture(scope="module")
def runs():
    square, octagon = (read_run(RUNS_DIR / name) for name in ("square-2laps", "octagon-2laps"))
    return {"square": lambda: square, "octagon": lambda: octagon}


def blitting_tuner(runs, canvas_class=FigureCanvasAgg) -> Tuner:
    fig = Figure(figsize=DEFAULT_FIGSIZE, dpi=100)
    canvas_class(fig)
    return Tuner(runs, fig, blit=True)


def pixels(fig: Figure) -> np.ndarray:
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int).copy()


def test_a_blitted_move_shows_what_a_full_draw_shows(runs):
    tuner = blitting_tuner(runs)
    tuner.apply()
    tuner.apply(sigma_range=0.01)  # the ellipses shrink, the path and the NIS points move
    blitted = pixels(tuner.figure)
    tuner.figure.canvas.draw()  # what a browser refresh or savefig draws
    full = pixels(tuner.figure)
    differ = np.any(np.abs(blitted - full) > 40, axis=-1)
    # a full draw puts the spines over the data and lets 20% of it through the legends' frames
    assert differ.mean() < 0.003, differ.mean()
    plain = Figure(figsize=DEFAULT_FIGSIZE, dpi=100)
    FigureCanvasAgg(plain)
    unblitted = Tuner(runs, plain, blit=False)
    unblitted.apply()
    unblitted.apply(sigma_range=0.01)
    plain.canvas.draw()
    assert np.array_equal(pixels(plain), full)  # and the figure itself is the same as unblitted


def test_the_background_is_drawn_again_only_when_the_axes_change(runs):
    tuner = blitting_tuner(runs)
    tuner.apply()
    for k in range(6):  # what a student's arrow keys do: one step down, one up
        tuner.apply(sigma_range=(0.03 / 10**0.1, 0.03)[k % 2])
    assert tuner.view.blitter.backgrounds == 1
    tuner.apply(run="octagon")  # another scene: new limits, new tick labels
    assert tuner.view.blitter.backgrounds == 2


class NotYetShown(FigureCanvasAgg):
    """Like an ipympl canvas before its front end sent 'initialized'."""

    syncing_data_url = True
    idle_draws = 0

    def draw_idle(self, *args, **kwargs) -> None:
        self.idle_draws += 1


def test_before_the_browser_shows_the_canvas_a_full_draw_is_requested(runs):
    tuner = blitting_tuner(runs, NotYetShown)
    tuner.apply()
    assert tuner.figure.canvas.idle_draws == 1 and tuner.view.blitter.backgrounds == 0
    tuner.figure.canvas.syncing_data_url = False  # the view is live: blit from now on
    tuner.apply(sigma_range=0.01)
    assert tuner.figure.canvas.idle_draws == 1 and tuner.view.blitter.backgrounds == 1


def test_panels_outside_a_browser_ask_for_full_draws(runs):
    fig = Figure()
    FigureCanvasAgg(fig)
    assert Tuner(runs, fig).view.blitter is None  # Agg alone, tests, scripts: as before


def test_after_an_idle_spell_a_change_runs_at_once():
    done = []

    async def main():
        coalescer = Coalescer(lambda value: done.append((value, time.monotonic())))
        started = time.monotonic()
        coalescer.request(1)
        await asyncio.sleep(0.2)
        return started

    started = asyncio.run(main())
    assert [v for v, _ in done] == [1]
    assert done[0][1] - started < COALESCE_DELAY  # no waiting: nothing else was queued


def _frame(canvas, get_diff_image) -> tuple[str, np.ndarray]:
    """One frame from `get_diff_image` without moving the canvas's diff state on."""
    state = (canvas._png_is_old, canvas._force_full, canvas._last_buff.copy())
    png = get_diff_image()
    canvas._png_is_old, canvas._force_full, canvas._last_buff = state
    return canvas._current_image_mode, np.asarray(Image.open(io.BytesIO(png)))


class Webagg(FigureCanvasWebAggCore):
    """webagg's canvas without a browser: a draw or a blit only marks the frame as new."""

    def draw(self) -> None:
        self._png_is_old = True
        FigureCanvasAgg.draw(self)

    def blit(self, bbox=None) -> None:
        self._png_is_old = True

    def draw_idle(self, *args, **kwargs) -> None:
        pass


def test_frames_are_encoded_faster_with_the_same_pixels(runs):
    tuner = blitting_tuner(runs, Webagg)
    canvas = tuner.figure.canvas
    assert "get_diff_image" in vars(canvas)  # installed on this canvas, not on the class
    tuner.apply()
    canvas.draw()
    canvas.get_diff_image()  # the first frame is full
    canvas.syncing_data_url = False
    tuner.apply(sigma_range=0.01)  # blitted: only the data changed
    for mode in ("diff", "full"):
        canvas._force_full = mode == "full"
        canvas._png_is_old = True
        ours = _frame(canvas, canvas.get_diff_image)
        webagg = _frame(canvas, lambda: FigureCanvasWebAggCore.get_diff_image(canvas))
        assert ours[0] == webagg[0] == mode
        np.testing.assert_array_equal(ours[1], webagg[1])
        if mode == "diff":
            assert 0 < (ours[1][..., 3] > 0).mean() < 0.2  # the changed pixels only
    assert PNG_COMPRESS_LEVEL == 1


@pytest.mark.parametrize("compressor", ["installed", "zlib"])
def test_png_bytes_decode_to_the_same_pixels(compressor, monkeypatch):
    if compressor == "zlib":  # the fallback where the isal wheel is missing
        monkeypatch.setattr(blit, "deflate", zlib.compress)
    rng = np.random.default_rng(3)
    for shape in ((1, 1, 4), (7, 13, 4), (600, 900, 4)):
        rgba = rng.integers(0, 256, shape, dtype=np.uint8)
        rgba[: shape[0] // 2] = 0  # a diff frame's transparent zeros, too
        decoded = Image.open(io.BytesIO(png_bytes(rgba)))
        assert decoded.mode == "RGBA"
        np.testing.assert_array_equal(np.asarray(decoded), rgba)


def test_a_diff_frame_is_smaller_than_pils_at_the_same_level(runs):
    tuner = blitting_tuner(runs, Webagg)
    canvas = tuner.figure.canvas
    tuner.apply()
    canvas.draw()
    canvas.get_diff_image()
    canvas.syncing_data_url = False
    tuner.apply(sigma_range=0.01)
    canvas._png_is_old = True
    ours = canvas.get_diff_image()
    rgba = np.asarray(Image.open(io.BytesIO(ours)))
    with io.BytesIO() as pil:
        Image.fromarray(rgba).save(pil, format="png", compress_level=PNG_COMPRESS_LEVEL)
        assert len(ours) < 0.95 * len(pil.getvalue())


def test_a_blitted_figure_is_not_left_stale(runs):
    # A kernel runs IPython's post_execute after every comm message (a slider move), and
    # pyplot's hook there requests a full draw of every stale figure: left stale, each move
    # cost a blit and then a full draw (seen in a kernel profile: 7 full draws in 12 moves).
    tuner = blitting_tuner(runs, Webagg)
    tuner.figure.canvas.syncing_data_url = False
    tuner.apply()
    assert not tuner.figure.stale
    tuner.apply(sigma_range=0.01)
    assert tuner.view.blitter.backgrounds >= 1
    assert not tuner.figure.stale


def test_moves_across_a_decade_of_nis_keep_the_axis_and_its_background(runs):
    # Found in the browser: with σr five times too small the largest NIS crossed 10**2 from one
    # key press to the next, so the NIS axis got new decade labels, and the whole background was
    # drawn again, on every move (330 ms in Voila against 50).
    tuner = blitting_tuner({"square": runs["square"]}, Webagg)
    tuner.figure.canvas.syncing_data_url = False
    sigma = tuner.settings.noise.sigma_range
    tuner.apply(sigma_range=sigma / 10**0.8)
    before = tuner.view.blitter.backgrounds
    for k in range(6):
        state = tuner.apply(sigma_range=sigma / 10 ** (0.9 if k % 2 == 0 else 0.8))
        nis = state.result.history.obs_nis
        top = math.log10(np.nanmax(nis))
        assert top <= tuner.view.nis_ax.get_ylim()[1]  # every point still on the axis
    assert tuner.view.blitter.backgrounds - before <= 1


@pytest.mark.parametrize("alpha", [255, 254, 128, 0])
def test_the_alpha_check_finds_one_pixel_short_of_opaque(alpha):
    rgba = np.full((60, 90, 4), 255, np.uint8)
    rgba[..., :3] = np.random.default_rng(5).integers(0, 256, (60, 90, 3), dtype=np.uint8)
    rgba[37, 71, 3] = alpha  # one pixel, whatever its colour
    buff = rgba.view(np.uint32).squeeze(2)
    assert transparent(rgba, buff) == (alpha != 255) == bool((rgba[..., 3] != 255).any())
    rgba[37, 71, :3] = 0  # black and opaque, or black and transparent: alpha alone decides
    assert transparent(rgba, buff) == (alpha != 255)


def test_the_true_path_and_tags_are_drawn_with_the_background_until_the_run_changes(runs):
    square = runs["square"]()
    tags = square.meta.tag_map
    moved = {i: np.add(xy, (0.03, 0.0)) for i, xy in tags.items()}  # 3 cm: same limits
    shifted = dataclasses.replace(square, meta=dataclasses.replace(square.meta, tag_map=moved))
    tuner = blitting_tuner({"square": lambda: square, "shifted": lambda: shifted})
    view = tuner.view
    tuner.apply()
    assert view.true_path not in view.blitter.artists()
    assert view.true_tags not in view.blitter.artists()
    tuner.apply(sigma_range=0.01)
    assert view.blitter.backgrounds == 1  # a move leaves the truth (and its pixels) alone
    limits = (view.map_ax.get_xlim(), view.map_ax.get_ylim())
    tuner.apply(run="shifted", sigma_range=0.01)
    assert (view.map_ax.get_xlim(), view.map_ax.get_ylim()) == limits  # only the truth moved
    assert view.blitter.backgrounds == 2  # ... and the background was drawn again
    x, _ = view.true_tags.get_data()
    np.testing.assert_allclose(np.sort(x), np.sort([xy[0] for xy in moved.values()]))
    blitted = pixels(tuner.figure)
    tuner.figure.canvas.draw()
    differ = np.any(np.abs(blitted - pixels(tuner.figure)) > 40, axis=-1)
    assert differ.mean() < 0.003, differ.mean()  # the shifted tags, as a full draw shows them
    tuner.apply(run="square", sigma_range=0.01)
    tuner.apply(run="square", sigma_range=0.02)
    assert view.blitter.backgrounds == 3  # back to the square's truth once, then moves only


def test_a_diff_frame_holds_the_changed_pixels_over_transparent_zeros():
    rng = np.random.default_rng(8)
    last = rng.integers(0, 2**32, (40, 70), dtype=np.uint32)
    buff = last.copy()
    buff[5:20, 10:60] = rng.integers(0, 2**32, (15, 50), dtype=np.uint32)
    buff[39, 69] ^= 1  # the last pixel, one bit
    decoded = Image.open(io.BytesIO(png_from_rows(png_rows(buff, changed=buff != last))))
    expected = np.where(buff != last, buff, 0)  # webagg's diff frame
    np.testing.assert_array_equal(np.asarray(decoded).view(np.uint32)[..., 0], expected)
    assert (np.asarray(decoded)[39, 69] == buff[39:, 69:].view(np.uint8)).all()
