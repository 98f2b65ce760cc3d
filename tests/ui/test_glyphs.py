"""The Table 1 row's glyph cache draws the picture matplotlib's Text draws, pixel for pixel."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text

from ekfslam.ui import glyphs
from ekfslam.ui.glyphs import CachedGlyphText

ROWS = (
    "ours    0.0231   0.0450   1.93   accepted 612",
    "ours    0.0198   0.0512   2.07   accepted 598",  # other digits at the same places
    "short row, another width: the centre moves by half a glyph",
)


def picture(cls, text: str, **props) -> np.ndarray:
    fig = Figure(figsize=(9, 6), dpi=100)
    FigureCanvasAgg(fig)
    fig.add_artist(cls(0.5, 0.93, text, family="monospace", fontsize=9.5, ha="center", **props))
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba()).copy()


@pytest.mark.parametrize("text", ROWS)
def test_cached_glyphs_draw_what_text_draws(text):
    glyphs._cache.clear()
    expected = picture(Text, text)
    assert (expected[..., :3] < 128).any()  # some ink
    cold, warm = picture(CachedGlyphText, text), picture(CachedGlyphText, text)
    np.testing.assert_array_equal(cold, expected)
    np.testing.assert_array_equal(warm, expected)
    assert 0 < len(glyphs._cache) <= len(text)  # one bitmap per glyph and subpixel offset


def test_what_the_cache_cannot_reproduce_is_drawn_by_text():
    glyphs._cache.clear()
    for props in ({"rotation": 30}, {"fontstyle": "italic", "rotation": 90}):
        np.testing.assert_array_equal(
            picture(CachedGlyphText, ROWS[0], **props), picture(Text, ROWS[0], **props)
        )
    assert not glyphs._cache


def test_other_renderers_get_texts_own_drawing(tmp_path):
    fig = Figure(figsize=(4, 1))
    fig.add_artist(CachedGlyphText(0.5, 0.5, ROWS[0], family="monospace"))
    fig.savefig(tmp_path / "row.svg")  # no Agg renderer: Text's own draw
    assert "<svg" in (tmp_path / "row.svg").read_text()
