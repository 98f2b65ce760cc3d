"""The pinhole camera: intrinsics, lens distortion, its place on the robot, and the tags it reads.

Frames used throughout (all right-handed):

- **world**: x, y on the floor, z up (the seed's Figure 1 seen from above).
- **robot**: x forward, y left, z up, origin at the robot's centre on the floor.
- **optical** (OpenCV's): z along the optical axis, x to the right in the image, y down.

A pixel is addressed the OpenCV way: the centre of pixel (column u, row v) has coordinates
(u, v), so the image spans [-0.5, width - 0.5] and the optical axis of a centred camera passes
through ((width - 1) / 2, (height - 1) / 2). A point P = (X, Y, Z) in the optical frame lands on

    u = fx · x' + cx,   v = fy · y' + cy,   (x', y') = distort(X / Z, Y / Z)

with OpenCV's radial-tangential distortion (k1, k2, p1, p2, k3).

This module needs only numpy; the image work is in `ekfslam.vision.render` and
`ekfslam.vision.detect`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.errors import ConfigError

Array = NDArray[np.float64]

#: The AprilTag family the arena's tags are printed from (36 data bits, Hamming distance 11).
TAG_FAMILY = "tag36h11"
#: m, the side of the arena's printed tags (the black square, `TagSpec.size`).
TAG_SIZE = 0.16
#: m, the height of the tags' centres above the floor.
TAG_HEIGHT = 0.15
#: (x, y, yaw) m, m, rad: where the seed's robot carries its camera, 6 cm ahead of its centre.
DEFAULT_MOUNTING = (0.06, 0.0, 0.0)
#: The printed tag's outline is its 8-module black square plus the white module around it.
_OUTLINE_SCALE = 10.0 / 8.0
_NEAR = 0.01  # m: a point must be at least this far in front of the optical centre


@dataclass(frozen=True)
class Camera:
    """A pinhole camera with OpenCV lens distortion, mounted level or pitched on the robot.

    width, height : image size, px.
    fx, fy : focal lengths, px.  cx, cy : principal point, px (OpenCV convention, see module).
    distortion : (k1, k2, p1, p2, k3), OpenCV's order; 4 or 5 numbers (k3 = 0 when 4).
    mount_height : m, the optical centre above the floor; needed to render, not to detect.
    pitch : rad, the optical axis below the horizontal (positive looks down).

    The camera's position and yaw in the robot frame are the run's ``camera_mounting``.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)
    mount_height: float | None = None
    pitch: float = 0.0

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value <= 0:
                raise ConfigError(f"Camera.{name} must be a positive whole number of pixels")
            object.__setattr__(self, name, int(value))
        for name in ("fx", "fy", "cx", "cy", "pitch"):
            value = float(getattr(self, name))
            if not math.isfinite(value):
                raise ConfigError(f"Camera.{name} must be finite, got {value!r}")
            object.__setattr__(self, name, value)
        if self.fx <= 0 or self.fy <= 0:
            raise ConfigError("Camera focal lengths fx, fy must be positive")
        dist = tuple(float(d) for d in self.distortion)
        if len(dist) not in (4, 5) or not all(math.isfinite(d) for d in dist):
            raise ConfigError(
                "Camera.distortion must be 4 or 5 finite numbers (k1, k2, p1, p2[, k3])"
            )
        object.__setattr__(self, "distortion", dist + (0.0,) * (5 - len(dist)))
        if self.mount_height is not None:
            h = float(self.mount_height)
            if not (math.isfinite(h) and h > 0):
                raise ConfigError("Camera.mount_height must be a positive height in m, or None")
            object.__setattr__(self, "mount_height", h)

    @property
    def K(self) -> Array:
        """The 3x3 intrinsic matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def dist(self) -> Array:
        """(5,) the distortion coefficients as OpenCV takes them."""
        return np.array(self.distortion, dtype=np.float64)

    @property
    def horizontal_fov(self) -> float:
        """Full horizontal field of view of the undistorted pinhole, rad."""
        return math.atan2(self.cx + 0.5, self.fx) + math.atan2(self.width - 0.5 - self.cx, self.fx)

    def project(self, points: ArrayLike) -> Array:
        """Pixels (N, 2) of points (N, 3) in the optical frame (Z > 0), distortion included."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        x, y = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
        k1, k2, p1, p2, k3 = self.distortion
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        return np.column_stack([self.fx * xd + self.cx, self.fy * yd + self.cy])

    def scaled(self, factor: int) -> Camera:
        """The same camera with `factor` x `factor` pixels per pixel (for supersampling).

        A pixel centre u at the original scale sits at factor · (u + 0.5) - 0.5 at the new one.
        """
        return Camera(
            self.width * factor,
            self.height * factor,
            self.fx * factor,
            self.fy * factor,
            factor * (self.cx + 0.5) - 0.5,
            factor * (self.cy + 0.5) - 0.5,
            self.distortion,
            self.mount_height,
            self.pitch,
        )


def pinhole_camera(
    width: int = 640,
    height: int = 480,
    horizontal_fov_deg: float = 65.0,
    distortion: tuple[float, ...] = (-0.08, 0.03, 0.0, 0.0, 0.0),
    mount_height: float | None = 0.12,
    pitch: float = 0.0,
) -> Camera:
    """A centred camera with square pixels and the given horizontal field of view.

    The defaults are the seed's robot as we model it: a 640x480 webcam with a 65 degree field of
    view (the simulator's), mild barrel distortion, 12 cm above the floor, looking level.
    """
    fx = (width / 2.0) / math.tan(math.radians(horizontal_fov_deg) / 2.0)
    return Camera(
        width,
        height,
        fx,
        fx,
        (width - 1) / 2.0,
        (height - 1) / 2.0,
        distortion,
        mount_height,
        pitch,
    )


@dataclass(frozen=True)
class TagSpec:
    """The printed tags: family and size.

    size : m, the side of the black square (AprilTag's "tag size": 8 of the 10 modules of a
        36h11 tag; the outermost module is white, and the paper around it should be too).
    """

    size: float
    family: str = TAG_FAMILY

    def __post_init__(self) -> None:
        if not (math.isfinite(self.size) and self.size > 0):
            raise ConfigError(f"TagSpec.size must be a positive length in m, got {self.size!r}")
        if self.family != TAG_FAMILY:
            raise ConfigError(f"only the {TAG_FAMILY} family is supported, got {self.family!r}")
        object.__setattr__(self, "size", float(self.size))


def optical_axes(yaw: float, pitch: float) -> Array:
    """The optical frame's x (right), y (down) and z (forward) axes as rows, in the robot frame.

    Parameters
    ----------
    yaw : rad, the camera's heading in the robot frame (``camera_mounting`` yaw).
    pitch : rad, positive tilts the optical axis down.

    Returns
    -------
    (3, 3) R with R @ v_robot = v_optical (and R.T maps optical vectors into the robot frame).
    """
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    right = [sy, -cy, 0.0]
    down = [-cy * sp, -sy * sp, -cp]  # forward × right, so that the rows stay orthonormal
    forward = [cy * cp, sy * cp, -sp]
    return np.array([right, down, forward])


def optical_to_robot(points: ArrayLike, mounting: ArrayLike, pitch: float = 0.0) -> Array:
    """Points (N, 3) from the optical frame to the robot frame, relative to the camera's height.

    mounting : (x, y, yaw) of the camera in the robot frame, m, m, rad (``camera_mounting``).
    The z of the result is height above the optical centre; x and y are what range and bearing
    need, so the mounting height does not enter.
    """
    mx, my, yaw = np.asarray(mounting, dtype=float)
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    return p @ optical_axes(yaw, pitch) + np.array([mx, my, 0.0])


def tags_in_view(
    camera: Camera,
    tags: TagSpec,
    mounting: ArrayLike,
    poses: ArrayLike,
    positions: ArrayLike,
    normals: ArrayLike,
    *,
    tag_height: float = TAG_HEIGHT,
    max_incidence: float = math.pi / 2,
    margin_px: float = 1.0,
) -> NDArray[np.bool_]:
    """Which wall tags are fully in view and facing the camera, from each robot pose.

    A tag is fully in view when its whole printed outline, the black square and the white
    module around it, is in front of the camera and projects (lens distortion included) at
    least `margin_px` inside the image, checked at the corners and at 8 points along each edge
    (barrel distortion bows the edges outwards). The white module counts because the vision
    needs it: `ekfslam.vision.detect` refuses a tag whose white border the image cuts (its edge fit
    would end at the border). A tag faces the camera when the angle between its normal and the
    line of sight from the optical centre to its centre, in 3-D, is at most `max_incidence`.
    This is the one definition the simulator (`ekfslam.sim.simulation.visible`) and the vision
    evaluation (`ekfslam.analysis.vision_eval`) share.

    Parameters
    ----------
    camera : Camera, with ``mount_height`` set.  tags : TagSpec, the printed size.
    mounting : (3,) the camera's (x, y, yaw) in the robot frame, m, m, rad.
    poses : (F, 3) robot poses (x, y, θ), m, m, rad.
    positions, normals : (n, 2) the tags' centres on their walls (m) and unit normals.
    tag_height : m, the tags' centres above the floor.  max_incidence : rad.

    Returns
    -------
    (F, n) bool.
    """
    if camera.mount_height is None:
        raise ValueError("tags_in_view needs Camera.mount_height (the camera's height, m)")
    P = np.asarray(poses, dtype=float).reshape(-1, 3)
    xy = np.asarray(positions, dtype=float).reshape(-1, 2)
    normal = np.asarray(normals, dtype=float).reshape(-1, 2)
    mx, my, yaw = np.asarray(mounting, dtype=float).reshape(3)
    # the outline in (right, up) units of half its side, from each corner towards the next
    square = np.array([[-1.0, 1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]])
    step = (np.arange(8) / 8.0)[:, None, None]
    outline = (square + step * (np.roll(square, -1, axis=0) - square)).reshape(-1, 2)  # (32, 2)
    half = 0.5 * _OUTLINE_SCALE * tags.size
    right = np.column_stack([-normal[:, 1], normal[:, 0]])  # facing the tag: -normal x z
    points = np.empty((len(xy), len(outline), 3))
    points[..., :2] = xy[:, None] + half * outline[None, :, :1] * right[:, None]
    points[..., 2] = tag_height + half * outline[None, :, 1]
    c, s = np.cos(P[:, 2]), np.sin(P[:, 2])
    centre = np.column_stack(
        [P[:, 0] + c * mx - s * my, P[:, 1] + s * mx + c * my, np.full(len(P), camera.mount_height)]
    )
    # into the camera's level frame (x forward, y left, z up), then the pitched optical frame
    d = points[None] - centre[:, None, None]  # (F, n, S, 3)
    ch, sh = (f(P[:, 2] + yaw)[:, None, None] for f in (np.cos, np.sin))
    level = np.stack([ch * d[..., 0] + sh * d[..., 1], ch * d[..., 1] - sh * d[..., 0], d[..., 2]])
    optical = np.moveaxis(level, 0, -1) @ optical_axes(0.0, camera.pitch).T
    ahead = optical[..., 2] > _NEAR
    optical[..., 2] = np.where(ahead, optical[..., 2], 1.0)  # keep the projection finite
    px = camera.project(optical.reshape(-1, 3)).reshape(*optical.shape[:-1], 2)
    low, high = -0.5 + margin_px, np.array([camera.width, camera.height]) - 0.5 - margin_px
    inside = ahead & np.all((px >= low) & (px <= high), axis=-1)
    sight = centre[:, None, :] - np.column_stack([xy, np.full(len(xy), tag_height)])[None]
    cos_incidence = np.einsum("fnk,nk->fn", sight[..., :2], normal) / np.maximum(
        np.linalg.norm(sight, axis=-1), 1e-12
    )
    facing = (cos_incidence > 0.0) & (cos_incidence >= math.cos(max_incidence))
    return np.all(inside, axis=-1) & facing
