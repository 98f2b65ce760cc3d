"""How long the live panel takes from a changed value to an updated figure (`benchmark`).

``python -m benchmarks tune --bench`` prints it per seed run; the browser's share is timed by
``tune --browser`` (`benchmarks.browser`).
"""

from __future__ import annotations

import io
import time
from collections.abc import Mapping

import numpy as np
from matplotlib.backends.backend_webagg_core import FigureCanvasWebAggCore, FigureManagerWebAgg
from matplotlib.figure import Figure

from ekfslam.ui.tuning import DEFAULT_FIGSIZE, RunSource, Tuner, seed_runs


def benchmark(runs: Mapping[str, RunSource] | None = None, repeats: int = 15) -> dict[str, dict]:
    """Time from a changed value to an updated figure, per run, in this process.

    Each sample changes σr (alternating two values) and times what the kernel does for it in the
    panel: replay, summary (eq. 17), artist updates, then the render ipympl's draw request runs,
    an Agg render of the whole figure (`DEFAULT_FIGSIZE`, 100 dpi) encoded to PNG. The browser's
    share (the round trip and the PNG decode) is not in it. Returns, per run, medians in ms:
    "median_ms" (the whole), "replay_ms", "update_ms" (replay to artists), "draw_ms", and
    "cpu_ms", the whole in this process's CPU time (steadier than wall time on a busy machine);
    "blit_ms", the same change as the panel draws it on ipympl (`ekfslam.ui.blit`: replay,
    artists, the data drawn over the cached background and the PNG frame of the changed
    pixels, as a webagg canvas sends it), of which "frame_ms" the frame (diff and PNG) and
    "frame_kib" its size.
    """
    # lazy: matplotlib's Agg canvas is only for this measurement, not for the panel's import
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    class _Canvas(FigureCanvasAgg):
        def draw_idle(self, *args, **kwargs) -> None:  # ipympl's: a message, no drawing
            pass

    out = {}
    for name, source in (runs or seed_runs()).items():
        fig = Figure(figsize=DEFAULT_FIGSIZE, dpi=100)
        _Canvas(fig)
        tuner = Tuner({name: source}, fig)
        tuner.apply()
        fig.canvas.print_png(io.BytesIO())  # warm the font and text caches
        blit_fig = Figure(figsize=DEFAULT_FIGSIZE, dpi=100)
        FigureManagerWebAgg(FigureCanvasWebAggCore(blit_fig), 1).web_sockets.add(_Socket())
        blitting = Tuner({name: source}, blit_fig, blit=True)
        blitting.apply()
        frames = _timed_frames(blit_fig.canvas)
        samples, blits = [], []
        for k in range(repeats):
            started = time.perf_counter()
            blitting.apply(sigma_range=(0.02, 0.04)[k % 2])
            blits.append(time.perf_counter() - started)
            cpu, started = time.process_time(), time.perf_counter()
            state = tuner.apply(sigma_range=(0.02, 0.04)[k % 2])
            updated = time.perf_counter()
            fig.canvas.print_png(io.BytesIO())
            done = time.perf_counter()
            samples.append(
                (
                    done - started,
                    state.replay_seconds,
                    updated - started,
                    done - updated,
                    time.process_time() - cpu,
                )
            )
        medians = (np.median(np.array(samples), axis=0) * 1e3).tolist()
        out[name] = dict(
            zip(("median_ms", "replay_ms", "update_ms", "draw_ms", "cpu_ms"), medians, strict=True)
        )
        out[name]["blit_ms"] = float(np.median(blits) * 1e3)
        seconds, sizes = np.array(frames).reshape(-1, 2).T
        out[name]["frame_ms"] = float(np.median(seconds) * 1e3)
        out[name]["frame_kib"] = float(np.median(sizes) / 1024)
        out[name]["samples"] = repeats
    return out


class _Socket:
    """A webagg client that takes the frames and the messages and does nothing with them."""

    def send_binary(self, png: bytes) -> None:
        pass

    def send_json(self, content: dict) -> None:
        pass


def _timed_frames(canvas) -> list[tuple[float, int]]:
    """Time each frame `canvas` makes (diff and PNG); returns the list it fills (s, bytes)."""
    samples: list[tuple[float, int]] = []
    make = canvas.get_diff_image  # `ekfslam.ui.blit.fast_png`'s, installed by the Tuner

    def timed():
        started = time.perf_counter()
        png = make()
        samples.append((time.perf_counter() - started, 0 if png is None else len(png)))
        return png

    canvas.get_diff_image = timed
    return samples
