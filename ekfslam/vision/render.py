"""Render the 8-bit frames the robot's camera would record in the seed's arena.

The scene, in the world frame of `ekfslam.core.camera` (x, y on the floor, z up), is built by
`ekfslam.vision.scene`: floor, walls, the eight tags on white sheets, and a cluttered room beyond.
`ArenaRenderer` draws it for one camera (intrinsics, distortion, height, pitch) mounted on the
robot, and `ArenaRenderer.truth` says where each tag really is in the image, with its true range
and bearing, for scoring `ekfslam.vision.detect`.

How a frame is made, and why:

1. Every surface is a textured rectangle, so it maps to the image by a homography. A surface is
   clipped to the part in front of the camera, its texture warped with one
   ``cv2.warpPerspective`` into the clipped polygon's bounding box, and painted in order (room,
   walls, floor, sheets): seen from inside a convex arena no later surface is hidden behind an
   earlier one, so no depth buffer is needed.
2. Room, walls and floor are drawn at one sample per pixel. A tag sheet, whose edges are what
   the vision measures, is drawn at `supersample` x `supersample` samples per pixel from the
   texture level with about one texel per sample, averaged down and blended by its coverage:
   its edges are anti-aliased and sit where the pinhole model puts them (to a few hundredths of
   a pixel; ``tests/vision/test_render.py`` checks the ink's area and centroid).
3. The drawing is on an undistorted canvas large enough for the lens distortion's pull, then
   remapped through the camera's distortion (OpenCV's model, as `Camera.project`).
4. The lens blurs (Gaussian, `blur_sigma`) and darkens the corners (`vignetting`), the
   auto-exposure wobbles (`exposure_jitter`) and the sensor adds read and shot noise before the
   8-bit quantisation (values clip at 255).

Deterministic: the textures depend on `RenderConfig.seed` only, and frame i's noise on
(seed, i), so the same call gives the same bytes. About 30 ms a frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.arena import SEED_ARENA, Arena
from ekfslam.core.camera import TAG_HEIGHT, Camera, TagSpec, optical_axes, tags_in_view
from ekfslam.errors import ConfigError
from ekfslam.geometry import wrap_angle
from ekfslam.vision.corners import undistort
from ekfslam.vision.scene import Surface, build_scene

Array = NDArray[np.float64]

_NEAR = 0.01  # m: surfaces are clipped to this depth in front of the optical centre


@dataclass(frozen=True)
class RenderConfig:
    """How the scene looks and how the sensor records it.

    Scene: wall_height m (0.35); tag_height m, the tag centres above the floor (0.15);
    sheet_size (w, h) m of the paper each tag is printed on (A4 portrait); clutter: draw the
    room's posters and the unknown tag (True).
    Sensor: supersample (2) sub-pixels per pixel and axis; blur_sigma px (0.6);
    vignetting (0.2) relative darkening at the image corners; exposure (1.0) gain, where 1 puts
    white paper at about 220 of 255; exposure_jitter (0.05) relative std per frame;
    read_noise DN (1.5); shot_noise DN per DN of signal (0.04, the variance's slope).
    seed : fixes textures and noise (0).
    """

    wall_height: float = 0.35
    tag_height: float = TAG_HEIGHT
    sheet_size: tuple[float, float] = (0.21, 0.297)
    clutter: bool = True
    supersample: int = 2
    blur_sigma: float = 0.6
    vignetting: float = 0.2
    exposure: float = 1.0
    exposure_jitter: float = 0.05
    read_noise: float = 1.5
    shot_noise: float = 0.04
    seed: int = 0

    def __post_init__(self) -> None:
        if int(self.supersample) != self.supersample or self.supersample < 1:
            raise ConfigError("RenderConfig.supersample must be a whole number >= 1")
        for name in ("wall_height", "tag_height", "exposure"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"RenderConfig.{name} must be positive")
        for name in ("blur_sigma", "vignetting", "exposure_jitter", "read_noise", "shot_noise"):
            if not getattr(self, name) >= 0:
                raise ConfigError(f"RenderConfig.{name} must be zero or positive")


@dataclass(frozen=True, eq=False)
class TagTruth:
    """Where a tag truly is for one camera pose (one row per tag of the arena).

    tag_id (n,); corners (n, 4, 2) px of the black square's corners, distortion included, in the
    order top-left, top-right, bottom-right, bottom-left as seen facing the tag; in_view (n,):
    the whole printed tag (white border included) in front of the camera and inside the image;
    incidence (n,) rad between the tag's normal and the line of sight; range (n,) m and
    bearing (n,) rad of the tag centre from the robot centre and heading, in the floor plane.
    """

    tag_id: NDArray[np.int64]
    corners: Array
    in_view: NDArray[np.bool_]
    incidence: Array
    range: Array
    bearing: Array


class ArenaRenderer:
    """Renders 8-bit grayscale frames of an arena for one camera.

    Parameters
    ----------
    camera : Camera, with ``mount_height`` set.
    tags : TagSpec, the printed tag size (black square side, m).
    mounting : (x, y, yaw) of the camera in the robot frame, m, m, rad.
    arena : Arena, default the seed's.
    config : RenderConfig.
    """

    def __init__(
        self,
        camera: Camera,
        tags: TagSpec,
        mounting: ArrayLike = (0.0, 0.0, 0.0),
        arena: Arena = SEED_ARENA,
        config: RenderConfig | None = None,
    ) -> None:
        if camera.mount_height is None:
            raise ValueError("the renderer needs Camera.mount_height (the camera's height, m)")
        self.camera, self.tags, self.arena = camera, tags, arena
        self.config = config if config is not None else RenderConfig()
        self.mounting = np.asarray(mounting, dtype=float).reshape(3)
        self._setup_canvas()
        rng = np.random.default_rng(np.random.SeedSequence([self.config.seed, 1]))
        c = self.config
        self._surfaces = build_scene(
            arena, tags, rng, c.wall_height, c.tag_height, c.sheet_size, c.clutter
        )

    # -- geometry ---------------------------------------------------------------------------

    def camera_pose(self, pose: ArrayLike) -> tuple[Array, Array]:
        """Optical centre C (3,) in the world and R (3, 3) with X_optical = R @ (X_world - C)."""
        x, y, theta = np.asarray(pose, dtype=float)
        mx, my, yaw = self.mounting
        c, s = math.cos(theta), math.sin(theta)
        centre = np.array([x + c * mx - s * my, y + s * mx + c * my, self.camera.mount_height])
        return centre, optical_axes(theta + yaw, self.camera.pitch)

    def truth(self, pose: ArrayLike, margin_px: float = 1.0) -> TagTruth:
        """Where every tag of the arena is in the image, and its true range and bearing.

        in_view is `ekfslam.core.camera.tags_in_view` (facing the camera at any angle): the one rule
        the simulator sees by.
        """
        centre, R = self.camera_pose(pose)
        half = self.tags.size / 2.0
        n = len(self.arena.tags)
        corners = np.full((n, 4, 2), np.nan)
        incidence = np.zeros(n)
        for k, tag in enumerate(self.arena.tags):
            mid = np.array([*tag.position, self.config.tag_height])
            right = np.array([-tag.normal[1], tag.normal[0], 0.0])  # facing the tag: -normal x z
            up = np.array([0.0, 0.0, 1.0])
            square = mid + half * np.array([-right + up, right + up, right - up, -right - up])
            cam_sq = (square - centre) @ R.T
            sight = centre - mid
            facing = float(np.dot(sight[:2], tag.normal))
            incidence[k] = math.acos(np.clip(facing / np.linalg.norm(sight), -1.0, 1.0))
            if np.all(cam_sq[:, 2] > _NEAR):
                corners[k] = self.camera.project(cam_sq)
        in_view = tags_in_view(
            self.camera,
            self.tags,
            self.mounting,
            np.asarray(pose, dtype=float)[None],
            self.arena.tag_positions(),
            np.array([t.normal for t in self.arena.tags]),
            tag_height=self.config.tag_height,
            margin_px=margin_px,
        )[0]
        d = self.arena.tag_positions() - np.asarray(pose, dtype=float)[:2]
        rng = np.hypot(d[:, 0], d[:, 1])
        bearing = wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - float(pose[2]))
        return TagTruth(self.arena.tag_ids, corners, in_view, incidence, rng, bearing)

    # -- drawing ----------------------------------------------------------------------------

    def render(self, pose: ArrayLike, frame: int = 0) -> NDArray[np.uint8]:
        """The 8-bit grayscale frame (height, width) the camera records at robot `pose` (x, y, θ).

        frame : the frame's index, which seeds its noise (same pose and index, same image).
        """
        canvas = self.radiance(pose)
        return self.expose(canvas, frame)

    def radiance(self, pose: ArrayLike) -> NDArray[np.float32]:
        """The noise-free image (height, width), float32 radiance before the sensor (1 = white)."""
        centre, R = self.camera_pose(pose)
        canvas = np.zeros(self._canvas_shape, dtype=np.float32)
        for surface in self._surfaces:
            self._paint(canvas, surface, centre, R)
        if self._map is not None:
            canvas = cv2.remap(canvas, *self._map, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        return canvas * self._vignette

    def expose(
        self, radiance: NDArray[np.float32], frame: int = 0, config: RenderConfig | None = None
    ) -> NDArray[np.uint8]:
        """Blur, exposure and sensor noise: radiance (height, width) -> 8-bit frame.

        config : the sensor settings to use instead of the renderer's (the scene stays).
        """
        c = config if config is not None else self.config
        rng = np.random.default_rng(np.random.SeedSequence([c.seed, 2, int(frame)]))
        image = radiance
        if c.blur_sigma > 0:
            image = cv2.GaussianBlur(image, (0, 0), c.blur_sigma)
        gain = 255.0 * c.exposure * (1.0 + c.exposure_jitter * rng.standard_normal())
        signal = image * np.float32(gain)
        sigma = np.sqrt(
            np.float32(c.read_noise**2) + np.float32(c.shot_noise) * np.maximum(signal, 0)
        )
        noisy = signal + sigma * rng.standard_normal(signal.shape, dtype=np.float32)
        return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)

    def _setup_canvas(self) -> None:
        """The undistorted canvas that covers the distorted image, and the remap between them."""
        cam = self.camera
        if not any(cam.distortion):
            self._canvas_shape, self._offset, self._map = (cam.height, cam.width), (0.0, 0.0), None
        else:
            u, v = np.arange(cam.width, dtype=np.float64), np.arange(cam.height, dtype=np.float64)
            grid = np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)
            ideal = undistort(grid, cam)  # where each output pixel looks, undistorted
            u0, v0 = math.floor(ideal[:, 0].min()) - 2, math.floor(ideal[:, 1].min()) - 2
            u1, v1 = math.ceil(ideal[:, 0].max()) + 2, math.ceil(ideal[:, 1].max()) + 2
            self._offset = (float(u0), float(v0))
            self._canvas_shape = (v1 - v0 + 1, u1 - u0 + 1)
            mx = (ideal[:, 0] - u0).reshape(cam.height, cam.width).astype(np.float32)
            my = (ideal[:, 1] - v0).reshape(cam.height, cam.width).astype(np.float32)
            self._map = cv2.convertMaps(mx, my, cv2.CV_16SC2)
        u0, v0 = self._offset
        self._K = np.array([[cam.fx, 0.0, cam.cx - u0], [0.0, cam.fy, cam.cy - v0], [0, 0, 1.0]])
        x = (np.arange(cam.width) - cam.cx) / (cam.width / 2.0)
        y = (np.arange(cam.height) - cam.cy) / (cam.width / 2.0)
        r2 = (x[None, :] ** 2 + y[:, None] ** 2) / (1.0 + (cam.height / cam.width) ** 2)
        self._vignette = (1.0 - self.config.vignetting * r2).astype(np.float32)

    def _paint(self, canvas: np.ndarray, surface: Surface, centre: Array, R: Array) -> None:
        """Paint one surface over the canvas; tag sheets supersampled and blended by coverage."""
        poly = _clip_near((surface.corners() - centre) @ R.T)
        if len(poly) < 3:
            return
        K = self._K
        px = (poly[:, :2] / poly[:, 2:3]) @ K[:2, :2].T + K[:2, 2]
        H, W = canvas.shape
        x0, y0 = max(math.floor(px[:, 0].min()), 0), max(math.floor(px[:, 1].min()), 0)
        x1, y1 = min(math.ceil(px[:, 0].max()) + 1, W), min(math.ceil(px[:, 1].max()) + 1, H)
        if x1 <= x0 or y1 <= y0:
            return
        s = self.config.supersample if len(surface.levels) > 1 else 1
        # canvas pixel centre x sits at s (x - x0 + 0.5) - 0.5 in the supersampled patch
        to_patch = np.array(
            [[s, 0.0, s * (0.5 - x0) - 0.5], [0.0, s, s * (0.5 - y0) - 0.5], [0.0, 0.0, 1.0]]
        )
        pixels_per_m = s * K[0, 0] / poly[:, 2].min()
        w, h = surface.size
        texture = surface.levels[-1]
        for level in surface.levels:  # the coarsest with a texel per pixel at the nearest point
            if level.shape[1] / w >= pixels_per_m:
                texture = level
                break
        su, sv = w / texture.shape[1], h / texture.shape[0]
        ru, rv, ro = R @ surface.u, R @ surface.v, R @ (surface.origin - centre)
        # texel (a, b) in OpenCV's convention has its centre at (a + 0.5, b + 0.5) texel units
        A = np.column_stack([su * ru, sv * rv, ro + 0.5 * su * ru + 0.5 * sv * rv])
        size = (s * (x1 - x0), s * (y1 - y0))
        patch = cv2.warpPerspective(
            texture, to_patch @ K @ A, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
        mask = np.zeros(size[::-1], dtype=np.uint8)
        pts = (px - [x0, y0] + 0.5) * s - 0.5
        cv2.fillConvexPoly(mask, np.rint(pts * 16).astype(np.int32), 1, cv2.LINE_8, shift=4)
        roi = canvas[y0:y1, x0:x1]
        shade = np.float32(surface.shade)
        if s == 1:
            np.copyto(roi, patch * shade, where=mask.astype(bool))
            return
        cover = cv2.resize(
            mask.astype(np.float32), (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA
        )
        paint = cv2.resize(patch * mask, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
        roi *= 1.0 - cover
        roi += paint * shade


def _clip_near(poly: Array) -> Array:
    """Clip a convex polygon (N, 3), optical frame, to Z >= _NEAR (Sutherland-Hodgman)."""
    out = []
    n = len(poly)
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        a_in, b_in = a[2] >= _NEAR, b[2] >= _NEAR
        if a_in:
            out.append(a)
        if a_in != b_in:
            t = (_NEAR - a[2]) / (b[2] - a[2])
            out.append(a + t * (b - a))
    return np.array(out).reshape(-1, 3)
