"""A camera time stamp's error, as the noise it adds to the sightings of one image.

MRCLAM's camera time stamps are off the odometry's by tenths of a second
(`ekfslam.logs.mrclam.defaults.MRCLAM_TIME_SIGMA`). A sighting taken at body rate (vx, vy, ω)
whose stamp is off by δt was taken from the pose at t + δt, off by u δt with u = (R(θ) (vx, vy),
ω) the pose's rate (eq. 6); its range and bearing move by g δt, g = H_pose u (eq. 14,
`time_shift`). Per sighting that is time_sigma² g gᵀ more noise (`shared_sighting_noise`; for a
robot only turning (ω time_sigma)² on the bearing, `sighting_noise`). One image has one δt, so
its sightings share it: the joint test carries the cross terms
(`ekfslam.core.filter.jcbb_kernels.predict_all`, `ekfslam.core.association.AssociationConfig`'s
``time_shared``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


def sighting_noise(Q: ArrayLike, omega: float, time_sigma: float) -> Array:
    """Q (2, 2) of a sighting taken while turning at omega rad/s whose time stamp may be off by
    time_sigma s: (omega time_sigma)² more bearing variance (`AssociationConfig.time_sigma`)."""
    Q = np.asarray(Q, dtype=float)
    if time_sigma and omega:
        Q = Q + np.diag([0.0, (omega * time_sigma) ** 2])
    return Q


def time_shift(z: ArrayLike, rate: tuple[float, float, float]) -> Array:
    """g (2,): d(range, bearing)/dδt of a sighting z = (r, b) taken at body rate (vx, vy, ω)
    when its time stamp is off by δt: H_pose u of eq. (14), u = (R(θ) (vx, vy), ω) the pose's
    rate (eq. 6), written in the sighting's own geometry (θ cancels)."""
    r, b = float(z[0]), float(z[1])
    vx, vy, w = rate
    cb, sb = math.cos(b), math.sin(b)
    return np.array([-(vx * cb + vy * sb), (vx * sb - vy * cb) / max(r, 1e-6) - w])


def shared_sighting_noise(
    Q: ArrayLike, zs: ArrayLike, rate: tuple[float, float, float], time_sigma: float
) -> Array:
    """(m, 2, 2): each sighting's own Q plus its share of the image's one time-stamp error,
    time_sigma² g gᵀ (`time_shift`); for a robot only turning, (ω time_sigma)² on the bearing,
    as `sighting_noise`. The update's noise with `AssociationConfig.time_shared`: the joint test
    carries the cross terms too (`jcbb_kernels.predict_all`), the updates one at a time only
    each sighting's own (see `AssociatingFilter.observe`)."""
    zs = np.asarray(zs, dtype=float).reshape(-1, 2)
    Qs = np.empty((len(zs), 2, 2))
    Qs[:] = np.asarray(Q, dtype=float)
    if time_sigma:
        for i, z in enumerate(zs):
            g = time_shift(z, rate)
            Qs[i] += time_sigma**2 * np.outer(g, g)
    return Qs


def image_noises(
    Q: ArrayLike,
    zs: ArrayLike,
    omega: float,
    velocity: tuple[float, float],
    time_sigma: float,
    shared: bool,
) -> tuple[Array, Array, tuple[float, float, float] | None]:
    """For the sightings zs (m, 2) of one image taken at body velocity (m/s) and turn rate omega
    (rad/s): the test's Q (2, 2), the updates' Q (2, 2) or (m, 2, 2), and the rate the joint test
    shares among them (None: none). shared: one error per image (`shared_sighting_noise` in the
    updates, the rate for the test's cross terms); else `sighting_noise` for both."""
    if not (shared and time_sigma):
        Q = sighting_noise(Q, omega, time_sigma)
        return Q, Q, None
    rate = (float(velocity[0]), float(velocity[1]), float(omega))
    return np.asarray(Q, dtype=float), shared_sighting_noise(Q, zs, rate, time_sigma), rate
