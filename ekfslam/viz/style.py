"""The figures' one text size, what stays readable on a classroom projector, and the colours and
line styles that tell several lines apart to a colour-blind reader too."""

from __future__ import annotations

#: pt, the size of every label, tick, legend and annotation the figures draw (titles one larger).
FONT = 11

#: Okabe & Ito's eight colours, distinct under every common colour-vision deficiency (their yellow
#: is left out: it vanishes on white), for figures with several lines of one kind (tags, runs).
CVD_SAFE_COLORS = ("#000000", "#E69F00", "#56B4E9", "#009E73", "#0072B2", "#D55E00", "#CC79A7")
#: Line styles and markers to pair with them, so that no two lines differ by colour alone.
LINE_STYLES = ("-", "--", "-.", ":")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")
