"""The figures' one text size: what stays readable on a classroom projector."""

from __future__ import annotations

#: pt, the size of every label, tick, legend and annotation the figures draw (titles one larger).
FONT = 11
