"""A default noise scaled for the log's odometry rate: tried, measured, not kept.

A tuned default is a density per second of driving, measured on logs of one odometry rate
(MRCLAM's, about 100 rows a second). Holding each row until the next misses how the speed changed
in between. Between rows k and k + 1 (Δ_k apart) the speed drifts by J_k = u_{k+1} - u_k; a random
walk with that drift has diffusion J_k² / Δ_k, and the increment the held row misses,
∫ (u(t) - u_k) dt over the interval, has variance J_k² Δ_k² / 3. Summed over the rows and divided
by the log's duration it is a density per second, as M is, read from the log alone.

Measured (``python -m studies.noise_default.study defaults``, the "rate term" setting): MRCLAM's
robots held 0.5-1 s at a time go from 7-15 of 20 within 0.12 m to 16-18 of 20, but Dataset 4
robot 2 as logged goes from 0.020 to 0.108 m on a 2% change of σθ, and four held robots stay
lost. The rescue that ships (`ekfslam.analysis.noise_fit.replay_rescued`: when the documented
noise is not ok, R scaled by the factor whose innovations are most likely) holds on more of them
and leaves every robot that was ok alone.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.noise import NoiseConfig


def odometry_hold_density(t: ArrayLike, twist: ArrayLike) -> NDArray[np.float64]:
    """(3,) variance per second (m²/s, m²/s, rad²/s) that holding each row until the next adds
    to the increment along body x, y and θ (see the module)."""
    t = np.asarray(t, dtype=float)
    u = np.asarray(twist, dtype=float)
    if len(t) < 2 or not t[-1] > t[0]:
        return np.zeros(3)
    dt = np.diff(t)
    jumps = np.diff(u, axis=0)
    return (jumps**2 * (dt**2)[:, None]).sum(axis=0) / (3.0 * (t[-1] - t[0]))


def with_odometry_rate(noise: NoiseConfig, t: ArrayLike, twist: ArrayLike) -> NoiseConfig:
    """`noise` with `odometry_hold_density` added to σx², σy², σθ²."""
    extra = odometry_hold_density(t, twist)
    sx, sy, st = (
        math.sqrt(s * s + float(e))
        for s, e in zip((noise.sigma_x, noise.sigma_y, noise.sigma_theta), extra, strict=True)
    )
    return dataclasses.replace(noise, sigma_x=sx, sigma_y=sy, sigma_theta=st)
