"""A camera time stamp's error, as the noise it adds to the sightings of one image.

MRCLAM's camera time stamps are off the odometry's by tenths of a second
(`ekfslam.logs.mrclam.defaults.MRCLAM_TIME_SIGMA`). A sighting taken at body rate (vx, vy, ω)
whose stamp is off by δt was taken from the pose at t + δt, off by u δt with u = (R(θ) (vx, vy),
ω) the pose's rate (eq. 6); its range and bearing move by g δt, g = H_pose u (eq. 14,
`time_shift`). Per sighting that is time_sigma² g gᵀ more noise (`shared_sighting_noise`; for a
robot only turning (ω time_sigma)² on the bearing, `sighting_noise`). One image has one δt, so
its sightings share it: the joint test carries the cross terms
(`ekfslam.core.filter.predictions.predict_all`, `ekfslam.core.association.AssociationConfig`'s
``time_shared``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.models import RANGE_BEARING, SensorModel

Array = NDArray[np.float64]


def sighting_noise(Q: ArrayLike, omega: float, time_sigma: float) -> Array:
    """Q (2, 2) of a sighting taken while turning at omega rad/s whose time stamp may be off by
    time_sigma s: (omega time_sigma)² more bearing variance (`AssociationConfig.time_sigma`)."""
    Q = np.asarray(Q, dtype=float)
    if time_sigma and omega:
        Q = Q + np.diag([0.0, (omega * time_sigma) ** 2])
    return Q


def time_shift(
    z: ArrayLike, rate: tuple[float, float, float], sensor: SensorModel = RANGE_BEARING
) -> Array:
    """g (2,): d(z)/dδt of a sighting z taken at body rate (vx, vy, ω) when its time stamp is off
    by δt: H_pose u of eq. (14), u the pose's rate (eq. 6), written in the sighting's own
    geometry (the robot at the origin, heading 0: the landmark where the sighting puts it)."""
    origin = np.zeros(3)
    H_pose, _ = sensor.H(origin, sensor.g(origin, np.asarray(z, dtype=float)))
    return H_pose @ np.asarray(rate, dtype=float)


def shared_sighting_noise(
    Q: ArrayLike,
    zs: ArrayLike,
    rate: tuple[float, float, float],
    time_sigma: float,
    sensor: SensorModel = RANGE_BEARING,
) -> Array:
    """(m, 2, 2): each sighting's own Q plus its share of the image's one time-stamp error,
    time_sigma² g gᵀ (`time_shift`); for a robot only turning, (ω time_sigma)² on the bearing,
    as `sighting_noise`. The update's noise with `AssociationConfig.time_shared`: the joint test
    carries the cross terms too (`ekfslam.core.filter.predictions.predict_all`), the updates
    one at a time only each sighting's own (see `AssociatingFilter.observe`)."""
    zs = np.asarray(zs, dtype=float).reshape(-1, 2)
    Qs = np.empty((len(zs), 2, 2))
    Qs[:] = np.asarray(Q, dtype=float)
    if time_sigma:
        for i, z in enumerate(zs):
            g = time_shift(z, rate, sensor)
            Qs[i] += time_sigma**2 * np.outer(g, g)
    return Qs


class TimeError(NamedTuple):
    """A camera's time-stamp error: sigma (s), and whether it is one per image (shared by its
    sightings) or one per sighting."""

    sigma: float
    shared: bool


def image_noises(
    Q: ArrayLike,
    zs: ArrayLike,
    rate: tuple[float, float, float],
    error: TimeError,
    sensor: SensorModel = RANGE_BEARING,
) -> tuple[Array, Array, tuple[float, float, float] | None]:
    """For the sightings zs (m, 2) of one image taken at body rate (vx, vy, ω) (m/s, rad/s):
    the test's Q (2, 2), the updates' Q (2, 2) or (m, 2, 2), and the rate the joint test shares
    among them (None: none). A shared error: `shared_sighting_noise` in the updates, the rate
    for the test's cross terms; else `sighting_noise` for both."""
    if not (error.shared and error.sigma):
        Q = sighting_noise(Q, rate[2], error.sigma)
        return Q, Q, None
    rate = (float(rate[0]), float(rate[1]), float(rate[2]))
    return np.asarray(Q, dtype=float), shared_sighting_noise(Q, zs, rate, error.sigma, sensor), rate
