"""Text whose glyph bitmaps are rendered once: the panel's Table 1 row, drawn on every move.

Why: a blitted move draws the data and one line of text, the Table 1 row (its numbers change
with every setting). Matplotlib's Agg renderer rasterises every glyph of a string again on each
draw (FreeType, about 60 glyphs here): in a profile of 20 seed-run moves that was the largest
piece of the blit after the deflate, more than all the data artists together.

`CachedGlyphText` draws like `matplotlib.text.Text` and keeps each glyph's bitmap, keyed by the
font, size, dpi, glyph, hinting and the pen's position within its pixel (FreeType's 1/64 px): a
glyph moved by whole pixels is the same bitmap moved, so the picture is the one Text draws,
pixel for pixel (tests/ui/test_glyphs.py). Only what the cache can reproduce exactly takes this
path: unrotated, unslanted glyphs on an Agg renderer of matplotlib 3.11's per-glyph kind; all
else (other backends, mathtext boxes, older matplotlib) is drawn by Text itself.
"""

from __future__ import annotations

import types

import numpy as np
from matplotlib.backends import backend_agg
from matplotlib.text import Text

#: Bitmaps kept per process (a glyph at one subpixel offset each); the row needs a few hundred.
CACHE_SIZE = 4096

_cache: dict[tuple, tuple[np.ndarray, int, int]] = {}


def supported(renderer: object) -> bool:
    """Whether `renderer` draws text glyph by glyph in the way `CachedGlyphText` reproduces."""
    return (
        isinstance(renderer, backend_agg.RendererAgg)
        and hasattr(renderer, "_draw_text_glyphs_and_boxes")
        and hasattr(backend_agg, "RenderMode")
    )


class CachedGlyphText(Text):
    """A `Text` whose glyphs are rasterised once per subpixel offset (see the module)."""

    def draw(self, renderer) -> None:
        if not supported(renderer):
            super().draw(renderer)
            return
        renderer._draw_text_glyphs_and_boxes = types.MethodType(_draw_glyphs, renderer)
        try:
            super().draw(renderer)
        finally:
            del renderer._draw_text_glyphs_and_boxes  # the class's own again


def _draw_glyphs(self, gc, x, y, angle, glyphs, boxes) -> None:
    """`RendererAgg._draw_text_glyphs_and_boxes` (matplotlib 3.11) with a bitmap cache."""
    glyphs = list(glyphs)
    plain = angle == 0 and not boxes and all(g[3] == 0 and g[4] == 1 for g in glyphs)
    if not plain:
        type(self)._draw_text_glyphs_and_boxes(self, gc, x, y, angle, glyphs, boxes)
        return
    flags, antialiased = backend_agg.get_hinting_flag(), gc.get_antialiased()
    mode = backend_agg.RenderMode.NORMAL if antialiased else backend_agg.RenderMode.MONO
    height = int(self.height)
    for font, size, index, _slant, _extend, dx, dy in glyphs:  # dy is upwards
        # the pen in FreeType's 26.6 fixed point, y upwards, exactly as Agg's own loop places it
        px, py = round(0x40 * (x + dx)), round(0x40 * (self.height - y + dy))
        key = (font.fname, size, self.dpi, index, flags, antialiased, px & 63, py & 63)
        hit = _cache.get(key)
        if hit is None:
            font.set_size(size, self.dpi)
            font._set_transform(np.array([[0x10000, 0], [0, 0x10000]]), [px & 63, py & 63])
            bitmap = font._render_glyph(index, flags, mode)
            buffer = np.array(bitmap.buffer, copy=True)
            if not antialiased:
                buffer *= 0xFF
            if len(_cache) >= CACHE_SIZE:
                _cache.clear()
            hit = _cache[key] = (buffer, bitmap.left, bitmap.top)
        buffer, left, top = hit
        left, top = left + (px >> 6), top + (py >> 6)  # whole pixels: the same bitmap, moved
        # draw_text_image's y is downwards and the bitmap's bottom side
        self._renderer.draw_text_image(buffer, left, height - top + buffer.shape[0], 0, gc)
