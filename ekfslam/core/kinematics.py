"""Mecanum-wheel kinematics: four wheel speeds <-> body twist (vx, vy, ωz).

The seed's robot is commanded by four wheel speeds; the filter works on the body twist that they
produce (seed Section 2.2, the proxy variables of eq. 4). Both directions are linear maps.

Wheel order and sign convention (top view, x forward, y to the left, rollers in the usual "X"
pattern seen from above, each wheel's speed positive when it rolls the robot forward)::

            +x (forward)
              ^
      w1 FL  \\ | /  w2 FR
              \\|/
    +y <------ o         lx: half the distance between the front and rear axles
              /|\\        ly: half the distance between the left and right wheels
      w3 RL  / | \\  w4 RR

    vx =  r/4           ( w1 + w2 + w3 + w4)
    vy =  r/4           (-w1 + w2 + w3 - w4)
    ωz =  r/(4 (lx+ly)) (-w1 + w2 - w3 + w4)

Four wheel speeds have one more degree of freedom than a planar twist: the combination
(w1 + w2 - w3 - w4), front wheels against rear, makes them fight each other and moves nothing.
`twist_to_wheels` never produces it, so twist -> wheels -> twist is exact, and
wheels -> twist -> wheels is the projection that removes that component.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam import checks
from ekfslam.errors import ConfigError
from ekfslam.fieldtypes import field_types, finite
from ekfslam.plausibility import MAX_SPEED, MAX_TURN_RATE, MAX_WHEEL_SPEED


@dataclass(frozen=True)
class MecanumGeometry:
    """Wheel radius and half-distances of a mecanum base, in metres.

    The defaults are those of a small classroom mecanum robot of the seed's kind; measure yours.
    """

    wheel_radius: float = 0.030
    lx: float = 0.068
    ly: float = 0.054

    def __post_init__(self) -> None:
        field_types(self)
        for name in ("wheel_radius", "lx", "ly"):
            value = getattr(self, name)
            if not finite(value) or value <= 0:
                raise ConfigError(
                    f"MecanumGeometry.{name} must be a positive length, got {value!r}"
                )

    @property
    def wheels_to_twist_matrix(self) -> NDArray[np.float64]:
        """The 3x4 matrix J with (vx, vy, ωz) = J @ (w1, w2, w3, w4)."""
        r, k = self.wheel_radius, self.lx + self.ly
        return (r / 4.0) * np.array(
            [
                [1.0, 1.0, 1.0, 1.0],
                [-1.0, 1.0, 1.0, -1.0],
                [-1.0 / k, 1.0 / k, -1.0 / k, 1.0 / k],
            ]
        )

    @property
    def twist_to_wheels_matrix(self) -> NDArray[np.float64]:
        """The 4x3 matrix with (w1, w2, w3, w4) = M @ (vx, vy, ωz); J @ M is the identity."""
        r, k = self.wheel_radius, self.lx + self.ly
        return (1.0 / r) * np.array(
            [
                [1.0, -1.0, -k],
                [1.0, 1.0, k],
                [1.0, 1.0, -k],
                [1.0, -1.0, k],
            ]
        )


def wheels_to_twist(wheels: ArrayLike, geometry: MecanumGeometry) -> NDArray[np.float64]:
    """Body twist from wheel speeds.

    Parameters
    ----------
    wheels : array (4,) or (N, 4)
        Wheel speeds (w1, w2, w3, w4) in rad/s, in the order FL, FR, RL, RR.
    geometry : MecanumGeometry

    Returns
    -------
    array (3,) or (N, 3)
        (vx, vy, ωz) in m/s, m/s, rad/s, in the body frame.
    """
    what = "wheel speeds (w1, w2, w3, w4) in rad/s"
    w = checks.rows(wheels, "wheels_to_twist: wheels", 4, what, bound=MAX_WHEEL_SPEED)
    checks.instance(
        geometry, MecanumGeometry, "wheels_to_twist: geometry", "e.g. MecanumGeometry()"
    )
    return w @ geometry.wheels_to_twist_matrix.T


def twist_to_wheels(twist: ArrayLike, geometry: MecanumGeometry) -> NDArray[np.float64]:
    """Wheel speeds (rad/s; FL, FR, RL, RR) for a body twist (vx, vy, ωz), shape (3,) or (N, 3)."""
    what = "a body twist (vx, vy, wz) in m/s, m/s, rad/s"
    v = checks.rows(twist, "twist_to_wheels: twist", 3, what, bound=max(MAX_SPEED, MAX_TURN_RATE))
    checks.instance(
        geometry, MecanumGeometry, "twist_to_wheels: geometry", "e.g. MecanumGeometry()"
    )
    return v @ geometry.twist_to_wheels_matrix.T


def wheel_noise_to_twist_covariance(
    wheel_sigma: float | ArrayLike, geometry: MecanumGeometry
) -> NDArray[np.float64]:
    """Covariance (3x3) of (vx, vy, ωz) from independent wheel-speed noise (std in rad/s).

    This is how the seed's "independent noise in these speeds" maps onto its proxy variables.
    """
    sigma = np.broadcast_to(np.asarray(wheel_sigma, dtype=float), (4,))
    J = geometry.wheels_to_twist_matrix
    return J @ np.diag(sigma**2) @ J.T
