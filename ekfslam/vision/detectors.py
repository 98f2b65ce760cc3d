"""The tag detectors: find AprilTag 36h11 tags and their four corners in a grayscale image.

Step 1 of the pipeline of `ekfslam.vision.detect`, which refines the corners, solves the pose and
goes to the robot frame. Two backends share one interface (`TagDetector`, returning `TagQuad`):
`OpenCVDetector` (``cv2.aruco``, the default: no extra dependency; its "subpix" corner refinement
is kept to show its inward bias) and `AprilTagDetector` (the AprilTag 3 reference library through
``pupil-apriltags``, used only if installed). `make_detector` picks one by name (`DETECTORS`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class TagQuad:
    """A tag found in a frame, before any geometry.

    tag_id : the decoded id.
    corners : (4, 2) px in the image given to the detector, OpenCV pixel convention, in the
        order top-left, top-right, bottom-right, bottom-left of the tag as printed.
    hamming : bits the decoder had to correct (0 is a clean read).
    """

    tag_id: int
    corners: Array
    hamming: int = 0


class TagDetector(Protocol):
    """Anything that finds 36h11 tags in an 8-bit grayscale image."""

    name: str

    def detect(self, gray: NDArray[np.uint8]) -> list[TagQuad]:
        """The tags in `gray` (H, W) uint8, corners as `TagQuad` describes."""
        ...


class OpenCVDetector:
    """``cv2.aruco.ArucoDetector`` with the AprilTag 36h11 dictionary.

    corner_refinement : "none" (default: contour corners, good to about half a pixel, which
        `refine_corners` then fits) or "subpix" (OpenCV's ``CORNER_REFINE_SUBPIX``, biased
        inwards: kept to show that bias).
    """

    def __init__(self, corner_refinement: str = "none") -> None:
        methods = {"none": cv2.aruco.CORNER_REFINE_NONE, "subpix": cv2.aruco.CORNER_REFINE_SUBPIX}
        if corner_refinement not in methods:
            raise ValueError(f"corner_refinement must be one of {', '.join(methods)}")
        self.name = "opencv" if corner_refinement == "none" else f"opencv-{corner_refinement}"
        params = cv2.aruco.DetectorParameters()
        params.cornerRefinementMethod = methods[corner_refinement]
        # two adaptive-threshold windows (3 and 23 px) instead of three: half the time, and
        # the same tags found over 300 rendered frames
        params.adaptiveThreshWinSizeStep = 20
        dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
        self._detector = cv2.aruco.ArucoDetector(dictionary, params)

    def detect(self, gray: NDArray[np.uint8]) -> list[TagQuad]:
        corners, ids, _ = self._detector.detectMarkers(gray)
        if ids is None:
            return []
        return [
            TagQuad(int(i), np.asarray(c, dtype=np.float64).reshape(4, 2))
            for i, c in zip(ids.ravel(), corners, strict=True)
        ]


class AprilTagDetector:
    """The AprilTag 3 reference detector (``pip install pupil-apriltags``; optional).

    Its corners come counter-clockwise from the top-right with pixel centres at +0.5; both are
    converted to `TagQuad`'s convention. Reads with more than `max_hamming` corrected bits are
    dropped: the library otherwise reports ids decoded from clutter.
    """

    name = "apriltag"

    def __init__(self, quad_decimate: float = 2.0, max_hamming: int = 1) -> None:
        try:
            import pupil_apriltags  # lazy: optional, only the 'apriltag' detector needs it
        except ImportError as err:
            raise ImportError(
                "the 'apriltag' detector needs pupil-apriltags: pip install pupil-apriltags"
            ) from err
        self._detector = pupil_apriltags.Detector(families="tag36h11", quad_decimate=quad_decimate)
        self.max_hamming = max_hamming

    def detect(self, gray: NDArray[np.uint8]) -> list[TagQuad]:
        found = self._detector.detect(np.ascontiguousarray(gray))
        return [
            TagQuad(int(d.tag_id), np.asarray(d.corners, float)[[1, 0, 3, 2]] - 0.5, d.hamming)
            for d in found
            if d.hamming <= self.max_hamming
        ]


DETECTORS = {
    "opencv": OpenCVDetector,
    "opencv-subpix": lambda: OpenCVDetector("subpix"),
    "apriltag": AprilTagDetector,
}


def make_detector(name: str = "opencv") -> TagDetector:
    """A detector by name: "opencv" (default), "opencv-subpix" or "apriltag" (pupil-apriltags)."""
    if name not in DETECTORS:
        raise ValueError(f"unknown detector {name!r}; choose one of {', '.join(DETECTORS)}")
    return DETECTORS[name]()
