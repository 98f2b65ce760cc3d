"""What `ekfslam.logs.mrclam.load.load_mrclam` read, kept and dropped: `MrclamLoadReport`.

Nothing of MRCLAM is dropped silently; this record counts it, and formats it for a terminal
(`MrclamLoadReport.summary`) and as JSON (`as_dict`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

BARCODES = "Barcodes.dat"  # the dataset's barcode -> subject table, named in the reasons below


@dataclass(frozen=True)
class MrclamLoadReport:
    """What `load_mrclam` read, kept and dropped; times in s on the dataset's clock.

    measurement_rows == measurements_kept + robot_sightings_dropped + unknown_barcodes_dropped
    + beyond_range_dropped. Without RobotN_Groundtruth.dat, groundtruth_rows is 0 and the two
    groundtruth times None. The checks of `ekfslam.logs.mrclam.checks`: max_range (m, None: no
    cut), barcode_swap_fixed (a known swap in Barcodes.dat undone) and barcode_swap_renamed (the
    kept sightings it renamed), time_offsets ({start_s, end_s}).
    The ``*_out_of_order`` counts are rows whose time is earlier than the row before (they were
    stably sorted). ``start_inside_groundtruth`` is False when the first odometry time lies
    outside [groundtruth_first_time, groundtruth_last_time] and the start pose was clamped to the
    nearest ground-truth pose.
    """

    dataset: str
    robot: int
    odometry_rows: int
    odometry_duplicate_times: int
    odometry_max_gap_s: float
    odometry_out_of_order: int
    measurement_rows: int
    measurements_kept: int
    robot_sightings_dropped: int
    unknown_barcodes_dropped: int
    unknown_barcodes: frozenset[int]
    measurement_out_of_order: int
    groundtruth_rows: int
    groundtruth_first_time: float | None
    groundtruth_last_time: float | None
    groundtruth_out_of_order: int
    start_time: float
    start_inside_groundtruth: bool
    max_range: float | None = None
    beyond_range_dropped: int = 0
    barcode_swap_fixed: bool = False
    barcode_swap_renamed: int = 0
    time_offsets: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """JSON-ready ``loaded`` (rows out of order were sorted, not dropped) and ``dropped``
        (count and reason); times in s, rounded to the ms."""
        span = None
        if self.groundtruth_first_time is not None and self.groundtruth_last_time is not None:
            span = [round(self.groundtruth_first_time, 3), round(self.groundtruth_last_time, 3)]
        loaded = {k: getattr(self, k) for k in _LOADED} | {
            "odometry_max_gap_s": round(self.odometry_max_gap_s, 3),
            "groundtruth_span_s": span,
            "start_time_s": round(self.start_time, 3),
            "time_offsets": self.time_offsets,
            "barcode_swap": {
                "fixed": self.barcode_swap_fixed,
                "sightings_renamed": self.barcode_swap_renamed,
                "reason": _SWAP_WHY if self.barcode_swap_fixed else None,
            },
        }
        robots = {"count": self.robot_sightings_dropped, "reason": _ROBOTS_WHY}
        unknown = {
            "count": self.unknown_barcodes_dropped,
            "reason": _UNKNOWN_WHY,
            "barcodes": sorted(self.unknown_barcodes),
        }
        far = {
            "count": self.beyond_range_dropped,
            "max_range_m": self.max_range,
            "reason": _far_why(self.max_range),
        }
        dropped = {"robot_sightings": robots, "unknown_barcodes": unknown, "beyond_range": far}
        return {"dataset": self.dataset, "robot": self.robot, "loaded": loaded, "dropped": dropped}

    def lines(self) -> tuple[str, str]:
        """ "loaded: ..." (what was read, with units) and "dropped: ..." (what and why)."""
        unsorted = sum(getattr(self, k) for k in _LOADED if k.endswith("out_of_order"))
        unknown = "".join(f" {b}," for b in sorted(self.unknown_barcodes)).rstrip(",")
        if self.groundtruth_first_time is None or self.groundtruth_last_time is None:
            truth = "no ground truth (no Robot*_Groundtruth.dat)"
        else:
            span = self.groundtruth_last_time - self.groundtruth_first_time
            truth = f"{self.groundtruth_rows} ground-truth rows over {span:.1f} s" + (
                "" if self.start_inside_groundtruth else " (the start clamped to it)"
            )
        off = self.time_offsets
        return (
            f"loaded: {self.odometry_rows} odometry rows (largest gap "
            f"{self.odometry_max_gap_s:.3f} s, {self.odometry_duplicate_times} duplicate times), "
            f"{self.measurements_kept} of {self.measurement_rows} measurements, {truth}"
            + (f"; {unsorted} rows out of time order, sorted" if unsorted else "")
            + (
                f"; measurements start {off['start_s']:+.3f} s after the odometry and end "
                f"{off['end_s']:+.3f} s before it"
                if off
                else ""
            )
            + (
                f"; {BARCODES}: {_SWAP_WHY}, {self.barcode_swap_renamed} sightings renamed"
                if self.barcode_swap_fixed
                else ""
            ),
            f"dropped: {self.robot_sightings_dropped} robot sightings ({_ROBOTS_WHY}), "
            f"{self.unknown_barcodes_dropped} sightings of unknown barcodes{unknown} "
            f"({_UNKNOWN_WHY}), {self.beyond_range_dropped} beyond range "
            f"({_far_why(self.max_range)})",
        )

    def summary(self) -> str:
        """A few lines for a terminal: the dataset, what was loaded, what was dropped and why."""
        return "\n  ".join([f"MRCLAM dataset {self.dataset}, robot {self.robot}", *self.lines()])


_LOADED = (
    "odometry_rows",
    "odometry_duplicate_times",
    "odometry_out_of_order",
    "measurement_rows",
    "measurements_kept",
    "measurement_out_of_order",
    "groundtruth_rows",
    "groundtruth_out_of_order",
    "start_inside_groundtruth",
)
_ROBOTS_WHY, _UNKNOWN_WHY = "other robots, not landmarks", f"not in {BARCODES}"
_SWAP_WHY = "barcodes of subjects 11 and 17 swapped back (published swapped)"


def _far_why(max_range: float | None) -> str:
    if max_range is None:
        return "no range cut"
    return f"range over {max_range:g} m, beyond the camera's reliable range"
