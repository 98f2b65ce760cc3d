"""Where a new landmark goes, by its sensor's model: delayed triangulation for a sensor that
needs two sightings (a bearing alone).

An invertible sensor places a landmark at its first sighting: g(pose, z) and its Jacobians
G_r, G_z (eq. 12, `ekfslam.core.filter.steps.place_landmark`). One bearing only says on which
ray the landmark lies, so a bearing-only sensor (a camera without depth) takes the field's
delayed initialisation (Bailey, "Constrained initialisation for bearing-only SLAM", ICRA 2003;
Solà's slamtb offers it beside undelayed inverse depth): at the first sighting the filter keeps
a copy of the pose in its state (a clone c = p, with Σ's pose rows: `ekfslam.core.filter.
delayed`), which every later correction updates as part of the state; at a later sighting
(pose b, z_b) whose ray meets the first at `FilterConfig.min_parallax` or more, the landmark is
placed where both sightings put it, and the clone is marginalised (its rows dropped).

`triangulated` is that placement, for any sensor with a `SensorModel.triangulate` (the first
guess) and h, H (everything else):

1. m₀ = triangulate(c, z_a, b, z_b), refined by Gauss-Newton on the two sightings' weighted
   innovations (a no-op when two bearings fix the point exactly; a range-only or 3-number
   sensor over-determines it): m minimises |z_a - h(c, m)|²_{Q_a⁻¹} + |z_b - h(b, m)|²_{Q_b⁻¹}.
2. Its Jacobians by the implicit function theorem at that minimum: with A = [H_l(c, m); H_l(b,
   m)] (2m x 2), W = diag(Q_a, Q_b)⁻¹ and L = (Aᵀ W A)⁻¹ Aᵀ W (2 x 2m): ∂m/∂(z_a, z_b) = L,
   G_a = ∂m/∂c = -L_a H_r(c, m) and G_b = ∂m/∂b = -L_b H_r(b, m) (L_a, L_b: L's columns for
   each sighting). The new landmark's covariance and its cross-covariance with the state are
   then eq. (12)'s over the pose and the clone: Σ[L, :] = G_b Σ[r, :] + G_a Σ[c, :] and
   Σ[L, L] = G_b Σ[r, r] G_bᵀ + G_a Σ[c, c] G_aᵀ + G_b Σ[r, c] G_aᵀ + G_a Σ[c, r] G_bᵀ
   + L diag(Q_a, Q_b) Lᵀ.
3. The placement waits (the first sighting stays held) until the rays meet at
   `FilterConfig.min_parallax` or more and the landmark's largest standard deviation is at most
   `FilterConfig.max_spread` of its distance (`too_spread`): a wider one is far from Gaussian
   along its ray (30 seeds of `tests/core/test_bearing_only.py`'s world, σ_φ = 0.01 rad, with
   a heading noise of 1e-4 rad²/s: a spread of 0.2 put the map's mean NEES at 8-11, 0.1 at 2.8,
   for its 2 degrees of freedom; with no spread limit the pose's NEES left its band).

Plain numpy on small arrays, run once per landmark (Python, whatever the backend).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.models import SensorModel

Array = NDArray[np.float64]

#: Gauss-Newton steps at most, and the step (m) below which the point has converged.
ITERATIONS, TOLERANCE = 10, 1e-10
#: The largest weighted residual |z - h|²_W the two sightings may leave at the triangulated
#: point (χ² 99% for 2 degrees of freedom): more, and they do not see one landmark.
RESIDUAL_LIMIT = 9.21


@dataclass(frozen=True, eq=False)
class Held:
    """One sighting as triangulation takes it: the pose (3,) it was made from (for a held one,
    its clone's current estimate), z (m,) and its noise Q (m, m)."""

    pose: Array
    z: Array
    Q: Array


@dataclass(frozen=True, eq=False)
class Placement:
    """Where two sightings put a landmark: landmark (2,) its mean; G_a (2, 3) ∂m/∂(the first
    sighting's pose), G_b (2, 3) ∂m/∂(the later's), L (2, 2m) ∂m/∂(z_a, z_b) and Q (2m, 2m)
    diag(Q_a, Q_b) (see the module)."""

    landmark: Array
    G_a: Array
    G_b: Array
    L: Array
    Q: Array


def parallax(pose_a: Array, pose_b: Array, landmark: Array) -> float:
    """The angle (rad, in [0, π]) at the landmark between the two positions it was seen from."""
    da = np.asarray(pose_a[:2], dtype=float) - landmark
    db = np.asarray(pose_b[:2], dtype=float) - landmark
    na, nb = math.hypot(*da), math.hypot(*db)
    if not (na > 0.0 and nb > 0.0):
        return 0.0
    return math.acos(max(-1.0, min(1.0, float(da @ db) / (na * nb))))


def triangulated(
    sensor: SensorModel, first: Held, later: Held, min_parallax: float
) -> tuple[Placement | None, bool]:
    """The landmark two sightings place, with its Jacobians (see the module), or None and
    whether to keep the first sighting held: True when they meet at less than `min_parallax`
    rad (wait for a wider baseline), False when they do not place one landmark (no meeting
    point, or a residual beyond `RESIDUAL_LIMIT`: hold the later sighting instead)."""
    a, b = np.asarray(first.pose, dtype=float), np.asarray(later.pose, dtype=float)
    m = np.asarray(sensor.triangulate(a, first.z, b, later.z), dtype=float)
    if m.shape != (2,) or not np.all(np.isfinite(m)):
        return None, False
    size = len(later.z)
    Q = np.zeros((2 * size, 2 * size))
    Q[:size, :size], Q[size:, size:] = first.Q, later.Q
    W = np.linalg.inv(Q)
    for _ in range(ITERATIONS):  # Gauss-Newton on the two sightings
        A, _, residual = _stacked(sensor, first, later, a, b, m)
        step = np.linalg.solve(A.T @ W @ A, A.T @ W @ residual)
        m = m + step
        if not np.all(np.isfinite(m)):
            return None, False
        if np.max(np.abs(step)) < TOLERANCE:
            break
    A, B, residual = _stacked(sensor, first, later, a, b, m)
    if not float(residual @ W @ residual) <= RESIDUAL_LIMIT:
        return None, False
    if parallax(a, b, m) < min_parallax:
        return None, True
    L = np.linalg.solve(A.T @ W @ A, A.T @ W)  # ∂m/∂(z_a, z_b), 2 x 2m
    G_a, G_b = -L[:, :size] @ B[:size], -L[:, size:] @ B[size:]
    return Placement(m, G_a, G_b, L, Q), False


def too_spread(covariance: Array, landmark: Array, pose: Array, max_spread: float) -> bool:
    """Is the new landmark's covariance (2, 2) too wide for the linearisation: its largest
    standard deviation more than `max_spread` times its distance from the robot? Two rays that
    meet at a small angle, or from poses whose headings are uncertain, put the landmark far
    along its ray with an error that is not Gaussian; the sightings then wait for more parallax
    (`FilterConfig.max_spread`)."""
    spread = math.sqrt(max(float(np.linalg.eigvalsh(covariance)[-1]), 0.0))
    return not spread <= max_spread * math.hypot(landmark[0] - pose[0], landmark[1] - pose[1])


def _stacked(
    sensor: SensorModel, first: Held, later: Held, a: Array, b: Array, m: Array
) -> tuple[Array, Array, Array]:
    """A = [H_l(a, m); H_l(b, m)] (2m, 2), B = [H_r(a, m); H_r(b, m)] (2m, 3) and the residual
    (z_a - h(a, m), z_b - h(b, m)) (2m,) of both sightings at m."""
    H_ra, H_la = sensor.H(a, m)
    H_rb, H_lb = sensor.H(b, m)
    residual = np.concatenate(
        (sensor.innovation(first.z, sensor.h(a, m)), sensor.innovation(later.z, sensor.h(b, m)))
    )
    return np.vstack((H_la, H_lb)), np.vstack((H_ra, H_rb)), residual
