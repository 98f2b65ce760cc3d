"""The filter's noise: motion R (eq. 9) and observation Q (eq. 11), and a run's default choices.

`NoiseConfig` is plain data every floor may use (the simulator states its own noise in it, the
loaders their tuned defaults). Which defaults a run gets is the loader's knowledge: it records them
in the run's metadata (`ekfslam.logs.runjson.RunMeta.defaults`, for instance MRCLAM's tuned
values from `ekfslam.logs.mrclam.defaults`); `default_noise` and `default_config` only read them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.models import observation_noise
from ekfslam.errors import ConfigError, WrongTypeError
from ekfslam.fieldtypes import field_types, finite, shown

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
        field_types(self)
        sigmas = ("sigma_x", "sigma_y", "sigma_theta", "sigma_range", "sigma_bearing")
        for name in (*sigmas, "sigma_range_per_m"):
            value = getattr(self, name)
            if not (finite(value) and value >= 0):
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
    _require_run(run, "default_config")
    return run.meta.filter_defaults or FilterConfig()


def default_noise(run: Any) -> NoiseConfig:
    """The documented starting noise for a run: its loader's (``run.meta.noise_defaults``), else
    `NoiseConfig()`.

    run : a `ekfslam.logs.runlog.RunLog` (anything whose ``meta`` has ``noise_defaults``).
    """
    _require_run(run, "default_noise")
    return run.meta.noise_defaults or NoiseConfig()


def _require_run(run: Any, function: str) -> None:
    """A run log (core cannot name `RunLog`: anything whose meta has the defaults)."""
    meta = getattr(run, "meta", None)
    if not (hasattr(meta, "noise_defaults") and hasattr(meta, "filter_defaults")):
        raise WrongTypeError(
            f"{function}: run must be a RunLog, got {shown(run)}: read a run folder first "
            "(ekfslam.read_run(folder))"
        )
