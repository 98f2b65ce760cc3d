"""The analysis floor: alignment, scores, consistency, robustness, benchmarks, studies.

Imports anything below it (pipeline, logs, sim, vision, core, teaching); never viz, ui or cli."""
