"""The analysis floor: alignment, scores, consistency, the MRCLAM and vision scores, lab checks.

Imports anything below it (pipeline, logs, sim, vision, core, teaching); never viz, ui or cli."""
