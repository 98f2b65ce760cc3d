"""From pixels to range and bearing: find AprilTags, refine corners, solve PnP, go to the robot.

The pipeline for one grayscale frame:

1. **Detect** (`ekfslam.vision.detectors.TagDetector`): find 36h11 tags and their four corners.
   Two backends share one interface: `OpenCVDetector` (``cv2.aruco``, the default: no extra
   dependency, and with the refinement below as accurate as the reference library and faster)
   and `AprilTagDetector` (the AprilTag 3 reference library through ``pupil-apriltags``, used
   only if installed); both live in `ekfslam.vision.detectors`.
   Detection runs on the undistorted image (`ekfslam.vision.corners.Undistorter`): near the image
   border barrel distortion bends a tag's sides enough for ``cv2.aruco`` to miss it.
2. **Refine** (`ekfslam.vision.corners.refine_corners`): the detectors' corners are biased (OpenCV's
   make the tag look smaller: +0.5 % in range at 1 m, growing with blur; see
   ``notebooks/11-pixels-to-range-bearing.ipynb``); refitting the tag's four sides is not.
3. **Pose** (`tag_pose`): ``cv2.solvePnP`` (``SOLVEPNP_SQPNP``; OpenCV 5's IPPE solvers fail
   on upright tags seen by a level camera) on the refined, undistorted corners gives the tag
   centre in the optical frame and the tag's normal.
4. **Robot frame**: through the camera mounting (`ekfslam.core.camera.optical_to_robot`) to the
   range and bearing of the seed's eq. (10), in the floor plane.

A tag is refused, and counted (`VisionCounts`), when its pose is not finite (or behind the
camera), its id is not in the map, it appears twice in one frame, it is cut by the image border,
or it is seen more edge-on than `VisionConfig.max_incidence`: such measurements are never passed
on to the filter.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.camera import Camera, TagSpec, optical_to_robot
from ekfslam.errors import ConfigError
from ekfslam.geometry import wrap_angle
from ekfslam.vision.corners import Undistorter, distort, refine_corners
from ekfslam.vision.detectors import DETECTORS, TagDetector, make_detector

Array = NDArray[np.float64]

#: Why a detected tag was not passed on: the keys of `VisionCounts.refused`.
REFUSALS = ("nonfinite", "unknown_id", "duplicate_id", "outside_frame", "edge_on")


# ---------------------------------------------------------------------------------------------
# Pose


def tag_object_points(size: float) -> Array:
    """(4, 3) the black square's corners in the tag frame (x right, y up, z out of the tag), m.

    Top-left, top-right, bottom-right, bottom-left: the order ``SOLVEPNP_IPPE_SQUARE`` wants.
    """
    s = size / 2.0
    return np.array([[-s, s, 0.0], [s, s, 0.0], [s, -s, 0.0], [-s, -s, 0.0]])


def tag_pose(ideal_corners: ArrayLike, camera: Camera, size: float) -> tuple[Array, Array, float]:
    """The tag's centre (3,) and normal (3,) in the optical frame, and the RMS reprojection (px).

    `ideal_corners` (4, 2) are undistorted pixels (from `refine_corners`); NaNs when no finite
    pose exists. Solved with ``SOLVEPNP_SQPNP`` (globally optimal, 0.1 ms), not the square
    solver ``SOLVEPNP_IPPE_SQUARE``: in OpenCV 5.0 IPPE fails on exactly our geometry, an
    upright tag seen by a level camera, whenever the corners are nearly noise-free (up to 5 cm
    off, or a NaN normal, on exact corners; ``tests/vision/test_detect.py`` keeps the case).
    """
    nan3 = np.full(3, np.nan)
    c = np.asarray(ideal_corners, dtype=np.float64).reshape(4, 1, 2)
    if not np.all(np.isfinite(c)):
        return nan3, nan3, math.nan
    obj = tag_object_points(size)
    try:
        ok, rvec, tvec = cv2.solvePnP(obj, c, camera.K, None, flags=cv2.SOLVEPNP_SQPNP)
    except cv2.error:
        return nan3, nan3, math.nan
    if not ok or not (np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
        return nan3, nan3, math.nan
    R, _ = cv2.Rodrigues(rvec)
    centre = np.asarray(tvec, dtype=float).ravel()
    cam = obj @ R.T + centre
    with np.errstate(divide="ignore", invalid="ignore"):
        px = cam[:, :2] / cam[:, 2:3] * [camera.fx, camera.fy] + [camera.cx, camera.cy]
    error = float(np.sqrt(np.mean(np.sum((px - c.reshape(4, 2)) ** 2, axis=1))))
    return centre, R[:, 2].copy(), error


# ---------------------------------------------------------------------------------------------
# Frames -> range and bearing


@dataclass(frozen=True)
class VisionConfig:
    """detector : a name of `DETECTORS`.  refine : fit the edges (True); False keeps the
    detector's corners (biased; for comparison).  max_incidence : rad, tags seen more edge-on
    than this are refused (75 degrees)."""

    detector: str = "opencv"
    refine: bool = True
    max_incidence: float = math.radians(75.0)

    def __post_init__(self) -> None:
        if self.detector not in DETECTORS:
            raise ConfigError(f"VisionConfig.detector must be one of {', '.join(DETECTORS)}")
        if not 0 < self.max_incidence <= math.pi / 2:
            raise ConfigError("VisionConfig.max_incidence must be in (0, pi/2] rad")


@dataclass(frozen=True, eq=False)
class TagObservation:
    """One accepted tag: what the filter gets (range, bearing; eq. 10) and how it was found.

    range m, bearing rad in [-π, π): the tag centre from the robot centre and heading, in the
    floor plane. position (3,) m: the tag centre in the robot frame (z relative to the camera).
    incidence rad: between the tag's normal and the line of sight. corners (4, 2): refined, in
    the recorded image. reprojection px: RMS PnP residual.
    """

    tag_id: int
    range: float
    bearing: float
    position: Array
    incidence: float
    corners: Array
    reprojection: float


@dataclass(frozen=True, eq=False)
class FrameResult:
    """What one frame gave: accepted observations (by id) and refused (id, reason) pairs."""

    observations: tuple[TagObservation, ...]
    refused: tuple[tuple[int, str], ...]


@dataclass(frozen=True)
class VisionCounts:
    """Totals over frames: frames, tags found, accepted, and refused by reason (`REFUSALS`)."""

    frames: int
    found: int
    accepted: int
    refused: dict[str, int] = field(default_factory=dict)

    def as_dict(self) -> dict[str, int]:
        """Flat JSON-ready counts, ``refused_<reason>`` for each reason."""
        out = {"frames": self.frames, "found": self.found, "accepted": self.accepted}
        return out | {f"refused_{r}": int(self.refused.get(r, 0)) for r in REFUSALS}


class TagObserver:
    """Turns frames into range and bearing for one camera, tag size and mounting.

    Parameters
    ----------
    camera : Camera (intrinsics and distortion; pitch is used, mount height is not).
    tags : TagSpec (the black square's side).
    mounting : (x, y, yaw) of the camera in the robot frame (run.json ``camera_mounting``).
    tag_ids : the ids in the map; others are refused. None accepts any id.
    config : VisionConfig.
    detector : a TagDetector to use instead of the one `config` names.
    """

    def __init__(
        self,
        camera: Camera,
        tags: TagSpec,
        mounting: ArrayLike = (0.0, 0.0, 0.0),
        tag_ids: Iterable[int] | None = None,
        config: VisionConfig | None = None,
        detector: TagDetector | None = None,
    ) -> None:
        self.camera, self.tags = camera, tags
        self.mounting = np.asarray(mounting, dtype=float).reshape(3)
        self.tag_ids = None if tag_ids is None else frozenset(int(i) for i in tag_ids)
        self.config = config if config is not None else VisionConfig()
        self.detector = detector if detector is not None else make_detector(self.config.detector)
        self._undistorter = Undistorter(camera)
        self._counts: Counter[str] = Counter()

    @property
    def counts(self) -> VisionCounts:
        """Totals over every frame observed so far."""
        c = self._counts
        refused = {r: c[r] for r in REFUSALS}
        return VisionCounts(c["frames"], c["found"], c["accepted"], refused)

    def _checked(self, image: np.ndarray) -> NDArray[np.uint8]:
        """`image` as the (H, W) uint8 the camera makes, or ValueError naming the mismatch."""
        image = np.asarray(image)
        if image.dtype != np.uint8:
            raise ValueError(
                f"image has dtype {image.dtype}: give 8-bit gray (uint8, 0-255), e.g. "
                "(image * 255).astype(np.uint8) for a float image in [0, 1]"
            )
        if image.ndim == 3 and image.shape[2] == 3:
            image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        if image.ndim != 2:
            raise ValueError(f"image has shape {image.shape}: give (H, W) gray or (H, W, 3) BGR")
        c = self.camera
        if image.shape != (c.height, c.width):
            raise ValueError(
                f"image is {image.shape[1]}x{image.shape[0]} px but the camera is "
                f"{c.width}x{c.height} px (run.json's camera image_size): ranges would be wrong"
            )
        return image

    def _inside(self, ideal_corners: Array) -> bool:
        """Whether the printed tag, white border included, lies inside the recorded image.

        A tag cut by the image border can still be decoded, but its sides then end at the
        border and their fitted lines are wrong.
        """
        c = np.asarray(ideal_corners, dtype=float)
        mid = c.mean(axis=0)
        outer = mid + 1.25 * (c - mid)  # the white module around the 8-module black square
        ring = np.concatenate([outer, 0.5 * (outer + np.roll(outer, -1, axis=0))])
        px = distort(ring, self.camera)
        size = np.array([self.camera.width, self.camera.height]) - 0.5
        return bool(np.all((px >= -0.5) & (px <= size)))

    def observe(self, gray: NDArray[np.uint8]) -> FrameResult:
        """Detect, refine, solve and transform every tag of one frame (H, W) uint8.

        A colour frame (H, W, 3) uint8 in OpenCV's BGR order is converted to gray first. Any
        other image raises ValueError saying what is wrong: the size must be the camera's
        (``image_size``; a smaller image would give ranges scaled by the ratio), the type uint8.
        """
        gray = self._checked(gray)
        quads = self.detector.detect(self._undistorter(gray))
        ids = Counter(q.tag_id for q in quads)
        ideal = [self._undistorter.to_ideal(q.corners) for q in quads]
        if quads and self.config.refine:
            ideal = list(refine_corners(gray, np.stack(ideal), self.camera))
        accepted, refused = [], []
        for quad, corners in zip(quads, ideal, strict=True):
            centre, normal, error = tag_pose(corners, self.camera, self.tags.size)
            reason = None
            if self.tag_ids is not None and quad.tag_id not in self.tag_ids:
                reason = "unknown_id"
            elif ids[quad.tag_id] > 1:
                reason = "duplicate_id"
            elif (
                not (np.all(np.isfinite(centre)) and np.all(np.isfinite(normal))) or centre[2] <= 0
            ):
                reason = "nonfinite"
            elif not self._inside(corners):
                reason = "outside_frame"
            else:
                cos_incidence = -float(np.dot(normal, centre)) / float(np.linalg.norm(centre))
                incidence = math.acos(min(1.0, abs(cos_incidence)))
                if incidence > self.config.max_incidence:
                    reason = "edge_on"
            if reason is not None:
                refused.append((quad.tag_id, reason))
                continue
            p = optical_to_robot(centre, self.mounting, self.camera.pitch)[0]
            accepted.append(
                TagObservation(
                    tag_id=quad.tag_id,
                    range=math.hypot(p[0], p[1]),
                    bearing=float(wrap_angle(math.atan2(p[1], p[0]))),
                    position=p,
                    incidence=incidence,
                    corners=distort(corners, self.camera),
                    reprojection=error,
                )
            )
        self._counts.update(
            {"frames": 1, "found": len(quads), "accepted": len(accepted)}
            | Counter(reason for _, reason in refused)
        )
        accepted.sort(key=lambda o: o.tag_id)
        return FrameResult(tuple(accepted), tuple(refused))


def observations_table(
    times: Sequence[float], results: Sequence[FrameResult]
) -> tuple[Array, NDArray[np.int64], Array, Array]:
    """Columns (t, tag_id, range, bearing) of every accepted observation, by time then id."""
    rows = [
        (t, o.tag_id, o.range, o.bearing)
        for t, r in zip(times, results, strict=True)
        for o in r.observations
    ]
    if not rows:
        return np.empty(0), np.empty(0, np.int64), np.empty(0), np.empty(0)
    t, i, rng, b = zip(*rows, strict=True)
    return np.array(t), np.array(i, dtype=np.int64), np.array(rng), np.array(b)


#: Hershey font scale of the overlay labels: about 15 px capitals on a 640 px frame, which a
#: 9-inch figure shows at 11 pt or more (white on black, readable on a projector)
LABEL_SCALE = 0.6


def label_box(
    image: NDArray[np.uint8], lines: tuple[str, ...], at: tuple[int, int], size: float
) -> None:
    """Draw `lines` white on a black box whose bottom-left is `at` (px), kept inside `image`."""
    font, pad = cv2.FONT_HERSHEY_SIMPLEX, 3
    sizes = [cv2.getTextSize(line, font, size, 1) for line in lines]
    step = max(h + b for (_, h), b in sizes) + pad
    width = max(w for (w, _), _ in sizes) + 2 * pad
    height = step * len(lines) + pad
    x = min(max(0, at[0]), image.shape[1] - width)
    top = min(max(0, at[1] - 4 - height), image.shape[0] - height)
    cv2.rectangle(image, (x, top), (x + width, top + height), (0, 0, 0), -1)
    for k, line in enumerate(lines):
        baseline = top + step * (k + 1) - sizes[k][1]
        cv2.putText(image, line, (x + pad, baseline), font, size, (255, 255, 255), 1, cv2.LINE_AA)


def annotate(gray: NDArray[np.uint8], result: FrameResult, scale: int = 1) -> NDArray[np.uint8]:
    """An RGB copy of a frame with each accepted tag's corners, id, range and bearing drawn.

    Corner 0 (the tag's top-left) is marked by a filled dot. `scale` enlarges the image first
    (nearest neighbour), so that sub-pixel corners can be seen.
    """
    image = cv2.cvtColor(gray, cv2.COLOR_GRAY2RGB)
    if scale > 1:
        image = cv2.resize(image, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    shift = 4  # fractional bits: OpenCV draws at sub-pixel positions
    for o in result.observations:
        px = (o.corners + 0.5) * scale - 0.5
        pts = np.rint(px * (1 << shift)).astype(np.int32)
        cv2.polylines(image, [pts], True, (0, 220, 0), 1, cv2.LINE_AA, shift)
        for k, p in enumerate(pts):
            cv2.circle(
                image,
                tuple(p),
                (3 if k == 0 else 2) << shift,
                (255, 60, 0),
                -1 if k == 0 else 1,
                cv2.LINE_AA,
                shift,
            )
        x, y = px.min(axis=0)
        lines = (f"tag {o.tag_id}", f"{o.range:.3f} m {math.degrees(o.bearing):+.1f} deg")
        label_box(image, lines, (int(x), int(y)), LABEL_SCALE * max(1, scale / 2))
    return image
