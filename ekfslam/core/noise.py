"""The filter's noise: motion R (eq. 9) and observation Q (eq. 11), and a run's default choices.

`NoiseConfig` is plain data every floor may use (the simulator states its own noise in it, the
loaders their tuned defaults). Which defaults a run gets is the loader's knowledge: it records them
in the run's metadata (`ekfslam.logs.runjson.RunMeta.defaults`, for instance MRCLAM's tuned
values from `ekfslam.logs.mrclam.defaults`); `default_noise` and `default_config` only read them.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.models import observation_noise
from ekfslam.errors import ConfigError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class NoiseConfig:
    """The hand-tuned noise of the seed: motion R (eq. 9) and observation Q (eq. 11).

    Motion noise is a random walk on the body-frame increment: over a prediction of dt seconds
    the increment u = (Δux, Δuy, Δθ) gets covariance M = diag(σx², σy², σθ²) · dt, which
    `ekfslam.core.models.motion_noise` maps into the state (R = V M Vᵀ). Splitting a control
    interval at a detection therefore adds up to the same noise as not splitting it.

    sigma_x, sigma_y : m/√s, the drift along and across the body axes after one second.
    sigma_theta : rad/√s.
    R_per_step : the seed's way instead: one fixed 3x3 state-space R for every prediction
        (as nested tuples). When given, sigma_x/y/theta are ignored.
    sigma_range : m, σ_r of eq. (11).
    sigma_bearing : rad, σ_φ of eq. (11).
    sigma_range_per_m : σ_r grows with the range: a sighting at r metres has
        σ_r = sigma_range + sigma_range_per_m · r (a depth or stereo camera, whose range error
        grows with distance). 0 (the default): one σ_r for every sighting.
    per_sighting : when a run's detections carry their own σ_r and σ_φ
        (`ekfslam.logs.runlog.Detections.sigma_range`, optional columns of detections.csv), use
        them instead of sigma_range and sigma_bearing (the default); False ignores them.
    `sighting_noise` gives the Q of each sighting of a run.
    """

    sigma_x: float = 0.01
    sigma_y: float = 0.01
    sigma_theta: float = 0.02
    R_per_step: tuple[tuple[float, float, float], ...] | None = None
    sigma_range: float = 0.03
    sigma_bearing: float = 0.03
    sigma_range_per_m: float = 0.0
    per_sighting: bool = True

    def __post_init__(self) -> None:
        sigmas = ("sigma_x", "sigma_y", "sigma_theta", "sigma_range", "sigma_bearing")
        for name in (*sigmas, "sigma_range_per_m"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ConfigError(f"NoiseConfig.{name} must be a finite non-negative number")
            if not math.isfinite(value * value):
                raise ConfigError(f"NoiseConfig.{name} = {value!r}: its square overflows")
        for name in ("sigma_range", "sigma_bearing"):
            # a σ whose square underflows (1e-170² = 0) gives a Q as singular as σ = 0
            if not getattr(self, name) ** 2 > 0:
                raise ConfigError(
                    f"NoiseConfig.{name} = {getattr(self, name)!r}: observation noise must be "
                    "positive and its square must not underflow (Q would be singular)"
                )
        if not isinstance(self.per_sighting, bool):
            raise ConfigError(
                f"NoiseConfig.per_sighting must be True or False, got {self.per_sighting!r}"
            )
        if self.R_per_step is not None:
            R = np.asarray(self.R_per_step, dtype=float)
            if R.shape != (3, 3) or not np.allclose(R, R.T) or np.linalg.eigvalsh(R).min() < 0:
                raise ConfigError("R_per_step must be a symmetric positive semi-definite 3x3")

    @property
    def Q(self) -> Array:
        """Eq. (11), 2x2."""
        return observation_noise(self.sigma_range, self.sigma_bearing)

    def motion_density(self) -> Array:
        """diag(σx², σy², σθ²): the increment covariance per second of driving, (3, 3)."""
        return np.diag([self.sigma_x**2, self.sigma_y**2, self.sigma_theta**2])

    def sighting_Q(
        self,
        ranges: ArrayLike,
        sigma_range: ArrayLike | None = None,
        sigma_bearing: ArrayLike | None = None,
    ) -> Array:
        """Eq. (11) for each sighting, (N, 2, 2): diag(σ_r², σ_φ²).

        ranges : (N,) m, the sightings' ranges (for `sigma_range_per_m`).
        sigma_range, sigma_bearing : (N,) each sighting's own σ (a run's, see `per_sighting`),
            or None for this config's; `sigma_range_per_m` adds to either.
        """
        r = np.asarray(ranges, dtype=float)
        s_r = (
            np.full(r.shape, self.sigma_range)
            if sigma_range is None
            else np.asarray(sigma_range, dtype=float)
        )
        s_b = (
            np.full(r.shape, self.sigma_bearing)
            if sigma_bearing is None
            else np.asarray(sigma_bearing, dtype=float)
        )
        s_r = s_r + self.sigma_range_per_m * r
        Q = np.zeros((len(r), 2, 2))
        Q[:, 0, 0], Q[:, 1, 1] = s_r**2, s_b**2
        return Q


def sighting_noise(noise: NoiseConfig, detections: Any) -> Array:
    """The Q of a run's sightings: `noise.Q` (2, 2) when every sighting has the same, else
    `NoiseConfig.sighting_Q` (N, 2, 2), from the detections' own σ (when they carry them and
    `noise.per_sighting`) and `noise.sigma_range_per_m`.

    detections : a `ekfslam.logs.runlog.Detections` (range, and the optional sigma_range and
        sigma_bearing).
    """
    own = noise.per_sighting and getattr(detections, "sigma_range", None) is not None
    if not own and noise.sigma_range_per_m == 0:
        return noise.Q
    if own:
        return noise.sighting_Q(detections.range, detections.sigma_range, detections.sigma_bearing)
    return noise.sighting_Q(detections.range)


def default_config(run: Any) -> FilterConfig:
    """The documented filter choices for a run: its loader's (``run.meta.filter_defaults``), else
    `FilterConfig()`.

    run : a `ekfslam.logs.runlog.RunLog` (anything whose ``meta`` has ``filter_defaults``).
    """
    return run.meta.filter_defaults or FilterConfig()


def default_noise(run: Any) -> NoiseConfig:
    """The documented starting noise for a run: its loader's (``run.meta.noise_defaults``), else
    `NoiseConfig()`; for a recorded run, with the variance its odometry's rate adds
    (`odometry_hold_density`, `with_odometry_rate`).

    A tuned default is a density per second of driving, measured on logs of one odometry rate
    (MRCLAM's, about 100 rows a second). Holding each row until the next misses how the speed
    changed in between, an error that grows with the interval: on MRCLAM's robots resampled to
    rows held for 0.5-1 s, the tuned default rejects 60-90% of the sightings and loses the robot
    (aligned map errors of 1-3 m), while the same default with this term added maps them within
    0.1 m (``studies/noise_default/``). On MRCLAM's own logs the term is 0.0016-0.003 rad²/s
    (σθ 0.05 -> 0.052-0.053 rad/√s). A simulated run's robot follows its commands exactly
    between rows, so it gets none.

    run : a `ekfslam.logs.runlog.RunLog` (anything whose ``meta`` has ``noise_defaults`` and
        ``source``, and with ``controls.t`` and ``control_twist()``).
    """
    noise = run.meta.noise_defaults or NoiseConfig()
    if getattr(run.meta, "source", None) != "recorded":
        return noise
    return with_odometry_rate(noise, run.controls.t, run.control_twist())


def odometry_hold_density(t: ArrayLike, twist: ArrayLike) -> Array:
    """(3,) variance per second of driving that holding each control row until the next adds to
    the increment along body x, y and θ: (m²/s, m²/s, rad²/s), M's diagonal's units.

    t : (N,) s, the rows' times. twist : (N, 3) body twist (vx, vy, ω) of each row.

    Between rows k and k + 1 (Δ_k apart) the true speed drifts by J_k = u_{k+1} - u_k. A random
    walk with that drift over Δ_k has diffusion J_k² / Δ_k, and the increment the held row misses,
    ∫ (u(t) - u_k) dt over the interval, then has variance (J_k² / Δ_k) Δ_k³ / 3 = J_k² Δ_k² / 3.
    Summed over the rows and divided by the log's duration it is a density per second, as M is:
    for evenly spaced rows J² Δ / 3, growing with the interval (and with how much the speed
    changes per row). Read from the log alone: no ground truth.
    """
    t = np.asarray(t, dtype=float)
    u = np.asarray(twist, dtype=float)
    if len(t) < 2 or not t[-1] > t[0]:
        return np.zeros(3)
    dt = np.diff(t)
    jumps = np.diff(u, axis=0)
    return (jumps**2 * (dt**2)[:, None]).sum(axis=0) / (3.0 * (t[-1] - t[0]))


def with_odometry_rate(noise: NoiseConfig, t: ArrayLike, twist: ArrayLike) -> NoiseConfig:
    """`noise` with `odometry_hold_density` of the controls (t, twist) added to σx², σy², σθ²
    (unchanged when it gives a fixed per-step R instead: it has no density to add to)."""
    if noise.R_per_step is not None:
        return noise
    extra = odometry_hold_density(t, twist)
    sx, sy, st = (
        math.sqrt(s * s + float(e))
        for s, e in zip((noise.sigma_x, noise.sigma_y, noise.sigma_theta), extra, strict=True)
    )
    return dataclasses.replace(noise, sigma_x=sx, sigma_y=sy, sigma_theta=st)
