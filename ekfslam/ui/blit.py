"""Redraw only what moved: the panel's data artists over a cached picture of the rest.

Why: a slider move changes the data (paths, tags, ellipses, NIS points, the Table 1 title) but
rarely the axes, and most of a full Agg draw is text: tick labels, legends and titles, typeset
again on every draw (about 85 of the 92 ms of a move, measured in process). So `Blitter` draws
the figure once without its data artists, keeps those pixels (and the legends' pixels, which a
full draw paints over the data), and for each move restores them, draws the data artists in
z-order and pastes the legends back. Whenever anything else may have changed (the axis limits,
the NIS ticks, the figure's size or dpi: see `key`) it draws the background again.

On an ipympl canvas the result goes to the browser at once (``canvas.blit``: webagg's
diff-PNG of the changed pixels), without the ``draw_idle`` round trip (kernel -> browser ->
kernel) that a full draw needs. The figure itself stays an ordinary one: every artist is
visible, so a full draw (a browser refresh, ``savefig``, the static PNG of an exported
notebook) shows the same picture, except that a pasted legend hides the data under it entirely
where a full draw's 0.8-opaque frame lets a little through.
"""

from __future__ import annotations

import struct
import sys
import types
import zlib
from collections.abc import Callable, Hashable, Sequence

try:  # ISA-L's deflate: the same zlib stream format, 30x faster here (see `png_bytes`)
    from isal.isal_zlib import compress as deflate
except ImportError:  # a platform without its wheel: the standard library's, slower
    from zlib import compress as deflate

import numpy as np
from matplotlib.artist import Artist
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.backends.backend_webagg_core import FigureCanvasWebAggCore
from matplotlib.figure import Figure

#: zlib level of the PNG frames sent to the browser. Measured on a seed-run move's diff frame
#: (4% of the pixels changed), alternately in one run: level 6 (PIL's default, what webagg uses)
#: 13.8 ms CPU and 47 KiB, level 1 9.4 ms and 62 KiB; over 127.0.0.1 or a classroom's network
#: the 15 KiB more cost less than the 4 ms.
PNG_COMPRESS_LEVEL = 1
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def can_blit(figure: Figure) -> bool:
    """Whether `figure`'s canvas is one whose blit reaches a browser (ipympl, webagg)."""
    return isinstance(figure.canvas, FigureCanvasWebAggCore)


def browser_ready(figure: Figure) -> bool:
    """False while an ipympl canvas has no view in a browser yet (``syncing_data_url``).

    Until then ipympl keeps each frame sent as a base64 ``_data_url`` for a static copy, and
    its front end, started later with that value set, fails to show any frame (ipympl 0.10:
    "drawImage ... in the 'broken' state"). So the first frame must come from the browser's
    own draw request, as without blitting.
    """
    return not getattr(figure.canvas, "syncing_data_url", False)


def fast_png(figure: Figure) -> None:
    """Make `figure`'s webagg canvas encode its frames at `PNG_COMPRESS_LEVEL`.

    Installs, on this canvas only, matplotlib 3.8-3.11's ``get_diff_image`` (a full frame, or
    the changed pixels over transparent ones) with two differences, the zlib level and the
    encoder (`png_bytes`, rows unfiltered): the pixels are the same.
    A canvas that is not webagg's is left alone.
    """
    if can_blit(figure):
        figure.canvas.get_diff_image = types.MethodType(_get_diff_image, figure.canvas)


def _get_diff_image(self):  # matplotlib.backends.backend_webagg_core, but for the level
    if self._png_is_old:
        pixels = np.asarray(self.get_renderer().buffer_rgba())
        buff = pixels.view(np.uint32).squeeze(2)  # a pixel per uint32: one comparison each
        if (
            self._force_full
            or buff.shape != self._last_buff.shape
            or transparent(pixels, buff)  # a diff cannot be overlaid on transparency
        ):
            self.set_image_mode("full")
            rows = png_rows(buff)
        else:
            self.set_image_mode("diff")
            rows = png_rows(buff, changed=buff != self._last_buff)
        self._last_buff = buff.copy()
        self._force_full = False
        self._png_is_old = False
        return png_from_rows(rows)
    return None


#: The smallest uint32 of an opaque RGBA pixel where alpha is the high byte (little-endian).
_OPAQUE = 0xFF000000


def transparent(pixels: np.ndarray, buff: np.ndarray) -> bool:
    """Whether any pixel of `pixels` (H x W x 4 RGBA, `buff` the same as one uint32 each) has
    alpha below 255.

    Why not ``(pixels[..., 3] != 255).any()``: that strided look at one byte in four costs
    0.34 ms a frame here; on a little-endian machine alpha is each uint32's high byte, so the
    smallest pixel tells (0.08 ms, one contiguous pass). Elsewhere: the byte-wise check.
    """
    if sys.byteorder == "little":
        return bool(buff.size) and int(buff.min()) < _OPAQUE
    return bool((pixels[..., 3] != 255).any())


def png_bytes(rgba: np.ndarray, level: int = PNG_COMPRESS_LEVEL) -> bytes:
    """`rgba` (height x width x 4, uint8) as a PNG: every row unfiltered, one zlib stream.

    Why not PIL: at any zlib level above 0 PIL tries all five PNG row filters on every row and
    keeps the best, which on a diff frame (mostly transparent zeros, where no filter helps)
    costs more than the compression itself. Measured on a seed-run move's diff frame,
    alternately in one run: PIL level 1 9.2 ms and 62 KiB, unfiltered rows through zlib 5.0 ms
    and 53 KiB. The deflate itself was then the largest piece of a move in the kernel (15 ms of
    66 at load 9): ISA-L's (`deflate`, the isal package) level 1 takes 0.4 ms for 48 KiB of
    the same 2.1 MB (zlib-ng 0.8 ms and 67 KiB, libdeflate 17 ms). Same pixels either way
    (tests/ui/test_blit.py).
    """
    return png_from_rows(png_rows(np.ascontiguousarray(rgba).view(np.uint32)[..., 0]), level)


def png_rows(buff: np.ndarray, changed: np.ndarray | None = None) -> np.ndarray:
    """The PNG scanlines of `buff` (height x width, a uint32 RGBA pixel each): per row the
    filter byte 0 (None: the bytes as they are), then the pixels; with `changed` (a boolean
    mask of buff's shape) only those pixels, the others transparent zeros: a diff frame.

    Why here and not ``np.where`` then a copy into the rows (webagg's way, then ours): one
    pass writes the pixels where they go, 1.2 ms against 2.7 for a 900 x 600 diff frame.
    """
    height, width = buff.shape
    rows = (np.empty if changed is None else np.zeros)((height, 1 + 4 * width), np.uint8)
    rows[:, 0] = 0
    np.copyto(rows[:, 1:].view(np.uint32), buff, where=True if changed is None else changed)
    return rows


def png_from_rows(rows: np.ndarray, level: int = PNG_COMPRESS_LEVEL) -> bytes:
    """The PNG of `png_rows`'s scanlines: one zlib stream (`deflate`), 8-bit RGBA."""
    height, width = rows.shape[0], (rows.shape[1] - 1) // 4
    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)  # 8-bit RGBA, no interlace
    idat = deflate(rows, level)
    return b"".join(
        (PNG_SIGNATURE, _chunk(b"IHDR", header), _chunk(b"IDAT", idat), _chunk(b"IEND", b""))
    )


def _chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


class Blitter:
    """Draws `artists` (the data) over a cached background; see the module docstring.

    Parameters
    ----------
    figure : an Agg-based figure (ipympl's canvas is one).
    artists : the artists a move changes, drawn in z-order over the background.
    overlays : artists a full draw paints over the data (the legends): their pixels are cached
        with the background and pasted back after the data.
    key : () -> hashable, the state of everything else (limits, ticks); a new value redraws the
        background.
    """

    def __init__(
        self,
        figure: Figure,
        artists: Callable[[], Sequence[Artist]],
        overlays: Sequence[Artist],
        key: Callable[[], Hashable],
    ) -> None:
        self.figure, self.artists, self.overlays, self.key = figure, artists, overlays, key
        self._background = None
        self._pasted: list = []
        self._key: Hashable = None
        self.backgrounds = 0  # how many times the background was drawn (for tests and benchmarks)
        fast_png(figure)

    def redraw(self) -> None:
        """Show the artists' current state: restore, draw the data, paste the legends, blit
        (and mark the figure as drawn); a full draw request (``draw_idle``) while the browser
        has no view (`browser_ready`)."""
        canvas, fig = self.figure.canvas, self.figure
        if not browser_ready(fig):
            canvas.draw_idle()
            return
        key = (self.key(), tuple(fig.bbox.bounds), fig.dpi)
        if self._background is None or key != self._key:
            self._draw_background()
            self._key = key
        else:
            canvas.restore_region(self._background)
        for artist in sorted(self.artists(), key=lambda a: a.get_zorder()):  # stable: as added
            if artist.get_visible():
                fig.draw_artist(artist)
        for region in self._pasted:
            canvas.restore_region(region)
        canvas.blit(fig.bbox)
        # The browser now shows the figure as it is. Left stale, the next comm message would
        # redraw it in full: a kernel runs IPython's post_execute after every comm message too,
        # and pyplot's hook there asks each stale figure for a full draw (ipympl: a "draw"
        # round trip, then about 85 ms of Agg in the kernel per move, more than the blit).
        fig.stale = False

    def _draw_background(self) -> None:
        canvas = self.figure.canvas
        shown = [a for a in self.artists() if a.get_visible()]
        for artist in shown:
            artist.set_visible(False)
        try:
            # Agg's draw only: webagg's own draw would also send this data-less frame out
            FigureCanvasAgg.draw(canvas)
        finally:
            for artist in shown:
                artist.set_visible(True)
        self._background = canvas.copy_from_bbox(self.figure.bbox)
        renderer = canvas.get_renderer()
        self._pasted = [
            canvas.copy_from_bbox(a.get_window_extent(renderer).padded(2))
            for a in self.overlays
            if a.get_visible()
        ]
        self.backgrounds += 1
