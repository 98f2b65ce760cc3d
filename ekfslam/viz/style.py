"""The figures' one text size, what stays readable on a classroom projector, and the colours and
line styles that tell several lines apart to a colour-blind reader too."""

from __future__ import annotations

#: pt, the size of every label, tick, legend and annotation the figures draw (titles one larger).
FONT = 11

#: dots per inch of the figures drawn for a projector: the animation's 14-inch figure is then
#: 1960 px wide, a 1920 x 1080 projector's width
PROJECTOR_DPI = 140

#: Okabe & Ito's eight colours, distinct under every common colour-vision deficiency (their yellow
#: is left out: it vanishes on white), for figures with several lines of one kind (tags, runs).
CVD_SAFE_COLORS = ("#000000", "#E69F00", "#56B4E9", "#009E73", "#0072B2", "#D55E00", "#CC79A7")
#: Line styles and markers to pair with them, so that no two lines differ by colour alone.
LINE_STYLES = ("-", "--", "-.", ":")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")

#: What each colour means in the maps (Figure 2, the animation, the notebooks' drawings), from
#: Okabe & Ito: the estimate vermillion, the truth bluish green, the uncertainty blue, the true
#: start black. Under simulated deuteranopia and protanopia every two of them stay at least
#: 20 CIELAB units apart (tests/viz/test_colour_vision.py), where the old red estimate and
#: green truth came within 7 (one olive). Each role also has its own marker: the estimate
#: hollow circles and a solid path, the truth filled squares, the start a star.
ESTIMATE = "#D55E00"
TRUTH = "#009E73"
UNCERTAINTY = "#0072B2"
START = "#000000"
#: a measurement drawn beside the estimate (notebook 05's update, step by step)
MEASUREMENT = "#000000"
