"""The MRCLAM loader's checks that the dataset's users report: each a decision, each counted.

- The barcode swap of Dataset 1. Its ``Barcodes.dat`` gives subject 11 barcode 18 and subject 17
  barcode 61; the truth is the other way round (a note in the ``data2input.m`` loader of
  github.com/CAOR-MINES-ParisTech/esde says "error in original dataset"). We checked it against
  the data, scoring the map both ways with the shipped noise: with the file as it is, the
  eq. (17) aligned map error of robots 1-5 is 0.85-0.88 m (average 0.87 m: landmarks 11 and 17
  sit where the other one is, and the alignment cannot fit both); with the two barcodes swapped,
  0.04-0.08 m (average 0.061 m). The published file is wrong. `fix_barcodes` swaps them back
  only when the file still says what the published Dataset 1 says, so a corrected copy is left
  alone, and the report counts the sightings it renamed.
- Sightings beyond the camera's reliable range. The dataset's users drop ranges beyond about
  6 m (`RELIABLE_RANGE`; the barcode's stripes are a few pixels wide there). We measured the cut
  with the shipped noise (`ekfslam.logs.mrclam.defaults.MRCLAM_NOISE`, whose wide sigma_range
  already lets the bearings carry the map): the five-robot average aligned map error goes from
  0.061 to 0.064 m on Dataset 1, 0.044 to 0.043 m on Dataset 4 and 0.054 to 0.075 m on Dataset 7
  (robot 5 0.042 to 0.112 m): a far sighting's bearing is worth more than its range costs. So the
  default, `DEFAULT_MAX_RANGE`, is None (no cut); ``max_range=6.0`` (``--max-range 6``) makes
  the cut. Whatever is cut is counted in the report, never dropped silently.
- The time offsets between odometry and measurements: both logs share the robot's clock, but
  they start and end at different times (`time_offsets`); reported, not changed.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: m: the range beyond which the dataset's users drop sightings.
RELIABLE_RANGE = 6.0
#: The loader's default cut: none (the cut at `RELIABLE_RANGE` scores worse; module docstring).
DEFAULT_MAX_RANGE: float | None = None

#: {dataset number: ((subject, barcode as published), (subject, barcode as published))}: the
#: pairs of subjects whose barcodes Barcodes.dat swaps, as the published file has them.
BARCODE_SWAPS: dict[str, tuple[tuple[int, int], tuple[int, int]]] = {"1": ((11, 18), (17, 61))}


def fix_barcodes(dataset: str, barcode_to_subject: dict[int, int]) -> tuple[dict[int, int], bool]:
    """{barcode: subject} with a known swap of `dataset` undone, and whether it was undone.

    Undone only when the mapping still holds the swap exactly as published (see the module
    docstring); any other mapping comes back unchanged.
    """
    swap = BARCODE_SWAPS.get(dataset)
    if swap is None:
        return barcode_to_subject, False
    (s1, b1), (s2, b2) = swap
    if barcode_to_subject.get(b1) != s1 or barcode_to_subject.get(b2) != s2:
        return barcode_to_subject, False
    fixed = dict(barcode_to_subject)
    fixed[b1], fixed[b2] = s2, s1
    return fixed, True


def swapped_subjects(dataset: str) -> tuple[int, int]:
    """The two subjects whose barcodes `fix_barcodes` swaps for `dataset` ((0, 0) for none)."""
    swap = BARCODE_SWAPS.get(dataset)
    return (swap[0][0], swap[1][0]) if swap else (0, 0)


def beyond_range(ranges: NDArray[np.float64], max_range: float | None) -> NDArray[np.bool_]:
    """Mask (N,) of the sightings whose range (m) is beyond `max_range` (None: none is)."""
    if max_range is None:
        return np.zeros(len(ranges), dtype=bool)
    return np.asarray(ranges) > max_range


def time_offsets(odometry_t: NDArray[np.float64], measurement_t: NDArray[np.float64]) -> dict:
    """How the measurement log sits on the odometry's clock (s, rounded to the ms).

    ``start_s``: first measurement minus first odometry row (positive: the odometry starts
    first); ``end_s``: last odometry row minus last measurement (positive: the odometry ends last).
    """
    return {
        "start_s": round(float(measurement_t[0] - odometry_t[0]), 3),
        "end_s": round(float(odometry_t[-1] - measurement_t[-1]), 3),
    }
