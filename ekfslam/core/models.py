"""The seed's models, each stated once: motion (eqs. 4-7), observation (eqs. 10-14) and a new
landmark (eq. 12), with their Jacobians.

Pose p = (x, y, θ) in m, m, rad. Control increment u = (Δux, Δuy, Δθ) in the body frame (eq. 4).
Observation z = (r, φ): range in m and bearing in rad, measured from the robot's heading (eq. 10).
Landmark m = (mx, my) in m.

The vocabulary is the seed's, with the Robotics Toolbox's names in the model records:

==================================  ==============  ===========================================
function                            record field    what it is
==================================  ==============  ===========================================
`motion`                            ``f``           the pose after an increment, eq. (6)
`motion_jacobian`                   ``F_x``         G = ∂f/∂pose, eq. (7)
`motion_control_jacobian`           ``F_v``         V = ∂f/∂u, the rotation of eq. (5)
`observation`                       ``h``           ẑ = (r, φ), eq. (13), with atan2
`observation_jacobians`             ``H``           H's two blocks ∂h/∂pose, ∂h/∂landmark, eq. (14)
`inverse_observation`               ``g``           where a sighting puts a landmark, eq. (12)
`inverse_observation_jacobians`     ``G``           ∂g/∂pose and ∂g/∂z
`innovation`                        ``innovation``  ν = z - ẑ, the bearing wrapped
`robot_observation`                 ``h``           another robot's (r, φ), eq. (13)'s form
`robot_observation_jacobians`       ``H``           its blocks ∂h/∂observer, ∂h/∂target
==================================  ==============  ===========================================

These functions are the only place the models are written. Everything that needs a model reads
it from here: the filter through its `MotionModel` and `SensorModel` (`ODOMETRY`,
`RANGE_BEARING`), in plain Python or compiled by numba from this very source
(`ekfslam.core.filter.compile`); the association methods, the literal F_x reference
(`ekfslam.teaching.reference`), the simulator. `ekfslam.teaching.derivations` derives the same
expressions with sympy, and the tests check that the two agree and that every Jacobian is the
finite difference of its function.

They are written so that numba compiles them unchanged: plain `math` on floats, small arrays
built from tuples. A new sensor is four such functions and an `innovation`, gathered in a
`SensorModel` of any measurement size (a bearing alone: h, H, `triangulate`, innovation), a new
robot a `MotionModel` of any control size (ARCHITECTURE.md, "Where a new sensor model goes").
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.geometry import wrap_angle

Array = NDArray[np.float64]

#: Squared range (m²) below which a landmark is "at the robot" and its bearing is undefined.
MIN_RANGE_SQUARED = 1e-12


class DegenerateGeometry(ValueError):
    """An observation that cannot be linearised: the landmark sits on the robot."""


# ----------------------------------------------------------------------------------- motion
def motion(pose: ArrayLike, u: ArrayLike, dt: float = 0.0) -> Array:
    """Predicted pose after the body-frame increment u, eqs. (5)-(6).

    Parameters
    ----------
    pose : array (3,)   (x, y, θ) at t-1.
    u : array (3,)      (Δux, Δuy, Δθ), eq. (4).
    dt : s, the step's duration: an increment is already integrated, so it is not read (a
        `MotionModel`'s functions all take it: a model of rates, such as a unicycle's (v, ω),
        integrates over it).

    Returns
    -------
    array (3,)  (x, y, θ) at t|t-1, θ wrapped to [-π, π).
    """
    x, y, theta = pose[0], pose[1], pose[2]
    c, s = math.cos(theta), math.sin(theta)
    return np.array((x + u[0] * c - u[1] * s, y + u[0] * s + u[1] * c, wrap_angle(theta + u[2])))


def motion_jacobian(pose: ArrayLike, u: ArrayLike, dt: float = 0.0) -> Array:
    """G: the 3x3 Jacobian of eq. (6) with respect to the pose (the block inside eq. 7); dt is
    not read (`motion`)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array(
        (
            (1.0, 0.0, -u[0] * s - u[1] * c),
            (0.0, 1.0, u[0] * c - u[1] * s),
            (0.0, 0.0, 1.0),
        )
    )


def motion_control_jacobian(pose: ArrayLike, u: ArrayLike = None, dt: float = 0.0) -> Array:
    """V: the 3x3 Jacobian of eq. (6) with respect to the control u (the rotation of eq. 5).
    It does not depend on u or dt (the record's F_v takes them, for models whose V does).

    A control-noise covariance M (in u-space) becomes the state-space motion noise R = V M Vᵀ.
    """
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array(((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0)))


def motion_noise(pose: ArrayLike, M: ArrayLike) -> Array:
    """R = V M Vᵀ (3x3): control-increment covariance M (3x3, u-space) mapped into the state."""
    V = motion_control_jacobian(pose)
    R = V @ np.asarray(M, dtype=float) @ V.T
    return 0.5 * (R + R.T)


# ------------------------------------------------------------------------------ observation
def _offset(pose: ArrayLike, landmark: ArrayLike) -> tuple[float, float, float]:
    """δ = landmark - robot position and q = δᵀδ of eq. (13), refusing a landmark on the robot."""
    dx = landmark[0] - pose[0]
    dy = landmark[1] - pose[1]
    q = dx * dx + dy * dy
    if not q > MIN_RANGE_SQUARED:
        raise DegenerateGeometry("the landmark sits on the robot: no bearing is defined there")
    return dx, dy, q


def observation(pose: ArrayLike, landmark: ArrayLike) -> Array:
    """ẑ = (r, φ): predicted range and bearing of a landmark, eq. (13), with atan2.

    The seed writes arctan(δy/δx) - θ, which is wrong by π whenever δx < 0; atan2 is right in all
    four quadrants. The bearing is wrapped to [-π, π).

    Raises
    ------
    DegenerateGeometry
        When the landmark is within 1e-6 m of the robot (no bearing is defined there).
    """
    dx, dy, q = _offset(pose, landmark)
    return np.array((math.sqrt(q), wrap_angle(math.atan2(dy, dx) - pose[2])))


def observation_jacobians(pose: ArrayLike, landmark: ArrayLike) -> tuple[Array, Array]:
    """The two non-zero blocks of H, eq. (14): ∂ẑ/∂pose (2x3) and ∂ẑ/∂landmark (2x2).

    Eq. (14) writes them side by side as a 2x5 matrix times the lift F_x,j; the filter uses the
    blocks directly.
    """
    dx, dy, q = _offset(pose, landmark)
    r = math.sqrt(q)
    H_pose = np.array(((-dx / r, -dy / r, 0.0), (dy / q, -dx / q, -1.0)))
    H_landmark = np.array(((dx / r, dy / r), (-dy / q, dx / q)))
    return H_pose, H_landmark


def innovation(z: ArrayLike, z_hat: ArrayLike) -> Array:
    """ν = z - ẑ (2,), the bearing's difference wrapped to [-π, π) (the seed forgets it)."""
    return np.array((z[0] - z_hat[0], wrap_angle(z[1] - z_hat[1])))


def inverse_observation(pose: ArrayLike, z: ArrayLike) -> Array:
    """Landmark position from the pose and one observation, eq. (12)."""
    angle = pose[2] + z[1]
    return np.array((pose[0] + z[0] * math.cos(angle), pose[1] + z[0] * math.sin(angle)))


def inverse_observation_jacobians(pose: ArrayLike, z: ArrayLike) -> tuple[Array, Array]:
    """Jacobians of eq. (12): ∂m/∂pose (2x3) and ∂m/∂z (2x2)."""
    angle = pose[2] + z[1]
    c, s = math.cos(angle), math.sin(angle)
    G_pose = np.array(((1.0, 0.0, -z[0] * s), (0.0, 1.0, z[0] * c)))
    G_z = np.array(((c, -z[0] * s), (s, z[0] * c)))
    return G_pose, G_z


# ------------------------------------------------------------- a robot seen by another robot
def robot_observation(observer: ArrayLike, target: ArrayLike) -> Array:
    """ẑ = (r, φ) of the target robot's centre seen from the observer's: eq. (13) with the
    target's position as the landmark. A robot's barcode is a landmark that moves, so the model
    is the landmark's; only its second block differs (`robot_observation_jacobians`).

    Raises
    ------
    DegenerateGeometry
        When the two robots' centres are within 1e-6 m.
    """
    return observation(observer, target)


def robot_observation_jacobians(observer: ArrayLike, target: ArrayLike) -> tuple[Array, Array]:
    """∂ẑ/∂observer (2x3) and ∂ẑ/∂target (2x3) of `robot_observation`: eq. (14)'s two blocks, the
    landmark's block padded with a zero column, since a target's heading does not move its
    centre."""
    H_observer, H_position = observation_jacobians(observer, target)
    H_target = np.array(
        ((H_position[0, 0], H_position[0, 1], 0.0), (H_position[1, 0], H_position[1, 1], 0.0))
    )
    return H_observer, H_target


def observation_noise(sigma_range: float, sigma_bearing: float) -> Array:
    """Q, eq. (11): diag(σ_r², σ_φ²) with σ_r in m and σ_φ in rad."""
    return np.diag([float(sigma_range) ** 2, float(sigma_bearing) ** 2])


# ----------------------------------------------------------------------------- the records
@dataclass(frozen=True)
class MotionModel:
    """How the robot moves (the Robotics Toolbox's vehicle model), for a control of any size.

    f(pose, u, dt) -> pose (3,); F_x(pose, u, dt) -> G (3, 3) = ∂f/∂pose; F_v(pose, u, dt) ->
    V (3, k) = ∂f/∂u, so that a control noise M (k, k) becomes R = V M Vᵀ (3, 3). u : (k,) the
    control, k = control_size: the seed's body-frame increment (Δux, Δuy, Δθ) (k = 3, dt not
    read), or rates such as a unicycle's (v, ω) (k = 2) that f integrates over the step's dt
    (s). The Jacobians see the control and dt (the Toolbox's ``Fv(x, odo)``). Each is plain math
    on small arrays (see the module). name : how messages call it.
    """

    f: Callable
    F_x: Callable
    F_v: Callable
    name: str
    control_size: int = 3

    def __post_init__(self) -> None:
        if not (isinstance(self.control_size, int) and self.control_size >= 1):
            raise ValueError(
                f"MotionModel {self.name!r}: control_size must be a whole number >= 1, got "
                f"{self.control_size!r}"
            )


@dataclass(frozen=True)
class SensorModel:
    """What a sensor measures of a landmark, and where its sightings put a new landmark.

    For a measurement of m = `size` numbers (2 for range and bearing, 1 for a bearing alone):
    h(pose, landmark) -> ẑ (m,), the predicted measurement (eq. 13 for range and bearing);
    H(pose, landmark) -> (H_r (m, 3), H_l (m, 2)), ∂h/∂pose and ∂h/∂landmark (eq. 14's blocks);
    innovation(z, z_hat) -> ν (m,), z - ẑ in the measurement's space (angles wrapped).
    A landmark is placed by one of two means (`ekfslam.core.initialisation`):

    - an invertible sensor (one sighting fixes the landmark): g(pose, z) -> landmark (2,),
      where a measurement puts it (eq. 12), and G(pose, z) -> (G_r (2, 3), G_z (2, m)), ∂g/∂pose
      and ∂g/∂z; the landmark is placed at its first sighting;
    - a sensor that needs two sightings (a bearing alone): g = G = None and triangulate(pose_a,
      z_a, pose_b, z_b) -> landmark (2,), where two sightings from two poses put it (NaN where
      they do not meet); the filter holds a first sighting and places the landmark at a later one
      with enough parallax, by delayed triangulation.

    Each is plain math on small arrays (see the module), so the filter compiles it. h and H may
    assume the landmark is not on the robot (the filter refuses such a sighting first,
    `MIN_RANGE_SQUARED`). name : how messages call it.
    """

    h: Callable
    H: Callable
    g: Callable | None
    G: Callable | None
    innovation: Callable
    name: str
    size: int = 2
    triangulate: Callable | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.size, int) and self.size >= 1):
            raise ValueError(
                f"SensorModel {self.name!r}: size (the numbers in one measurement) must be a "
                f"whole number >= 1, got {self.size!r}"
            )
        if (self.g is None) != (self.G is None):
            raise ValueError(f"SensorModel {self.name!r}: give both g and G, or neither")
        if self.g is None and self.triangulate is None:
            raise ValueError(
                f"SensorModel {self.name!r}: a sensor without g (one sighting does not fix a "
                "landmark) needs triangulate(pose_a, z_a, pose_b, z_b) to place one from two"
            )

    @property
    def invertible(self) -> bool:
        """Does one sighting place a landmark (g, G), or does it take two (`triangulate`)?"""
        return self.g is not None


@dataclass(frozen=True)
class RelativeModel:
    """What one robot measures of another: the model of a sighting that links two pose blocks.

    h(observer, target) -> ẑ (2,); H(observer, target) -> (H_a (2, 3), H_b (2, 3)), ∂h/∂observer
    and ∂h/∂target; innovation(z, z_hat) -> ν (2,). The two poses are (x, y, θ) blocks of one
    state; a correction with it changes both robots (and, through Σ, the map). name : how
    messages call it.
    """

    h: Callable
    H: Callable
    innovation: Callable
    name: str


#: The seed's robot: a body-frame increment composed onto the pose, eqs. (4)-(7).
ODOMETRY = MotionModel(f=motion, F_x=motion_jacobian, F_v=motion_control_jacobian, name="odometry")

#: The seed's camera: range and bearing of a tag from the robot's centre, eqs. (10)-(14), (12).
RANGE_BEARING = SensorModel(
    h=observation,
    H=observation_jacobians,
    g=inverse_observation,
    G=inverse_observation_jacobians,
    innovation=innovation,
    name="range-bearing",
)

#: A robot's range and bearing to another robot's centre (MRCLAM's barcodes on the robots).
ROBOT_RANGE_BEARING = RelativeModel(
    h=robot_observation,
    H=robot_observation_jacobians,
    innovation=innovation,
    name="robot range-bearing",
)
