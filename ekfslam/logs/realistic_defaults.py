"""The realistic robot's noise: what a simulated run with `ekfslam.sim.config.REALISTIC`'s
errors replays with by default.

The simulator names it in ``RunMeta.defaults`` ("realistic"), which run.json keeps, so
``python -m ekfslam run data/runs/square-2laps-realistic`` replays with it, as MRCLAM's runs
replay with theirs (`ekfslam.logs.mrclam.defaults`). The values are
`ekfslam.sim.scenarios.realistic_noise()` to three digits (a test holds them equal); that
function says where each comes from. The simulator sits on this floor's level and imports it,
so the numbers are written here rather than computed.
"""

from __future__ import annotations

from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.noise import NoiseConfig

#: The name `ekfslam.logs.runjson.RunMeta.defaults` holds for these.
NAME = "realistic"

#: The ideal robot's `NoiseConfig()` grown by the errors the filter does not model, at their
#: typical size (`ekfslam.sim.scenarios.realistic_noise`): σ_r 0.03 -> 0.086 m (a 9 % range
#: scale at 0.9 m), σ_φ 0.03 -> 0.189 rad (0.3 rad/s of turning times 0.3 s of camera
#: latency and 0.3 s of motor lag, and the camera's 0.05 rad yaw error), σ_x, σ_y 0.010 ->
#: 0.0109 m/√s and σ_θ 0.020 -> 0.0203 rad/√s (the wheels' scale errors and the random part
#: of the slip).
REALISTIC_NOISE = NoiseConfig(
    sigma_x=0.0109, sigma_y=0.0109, sigma_theta=0.0203, sigma_range=0.0864, sigma_bearing=0.189
)

#: The filter's choices stay the generic ones: with `REALISTIC_NOISE` the gate rejects almost
#: nothing and re-initialises no landmark, so there is nothing to change.
REALISTIC_CONFIG = FilterConfig()

#: What `ekfslam.logs.runjson.TUNED_DEFAULTS` holds under `NAME`: (noise, filter choices).
DEFAULTS = (REALISTIC_NOISE, REALISTIC_CONFIG)
