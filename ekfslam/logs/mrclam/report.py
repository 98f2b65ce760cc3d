"""What `ekfslam.logs.mrclam.load.load_mrclam` read, kept and dropped: `MrclamLoadReport`.

Nothing of MRCLAM is dropped silently; this record counts it, and formats it for a terminal
(`MrclamLoadReport.summary`) and as JSON (`as_dict`).
"""

from __future__ import annotations

from dataclasses import dataclass

BARCODES = "Barcodes.dat"  # the dataset's barcode -> subject table, named in the reasons below


@dataclass(frozen=True)
class MrclamLoadReport:
    """What `load_mrclam` read, kept and dropped; times in s on the dataset's clock.

    measurement_rows == measurements_kept + robot_sightings_dropped + unknown_barcodes_dropped.
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
    groundtruth_first_time: float
    groundtruth_last_time: float
    groundtruth_out_of_order: int
    start_time: float
    start_inside_groundtruth: bool

    def as_dict(self) -> dict:
        """JSON-ready ``loaded`` (rows out of order were sorted, not dropped) and ``dropped``
        (count and reason); times in s, rounded to the ms."""
        first, last = round(self.groundtruth_first_time, 3), round(self.groundtruth_last_time, 3)
        loaded = {k: getattr(self, k) for k in _LOADED} | {
            "odometry_max_gap_s": round(self.odometry_max_gap_s, 3),
            "groundtruth_span_s": [first, last],
            "start_time_s": round(self.start_time, 3),
        }
        robots = {"count": self.robot_sightings_dropped, "reason": _ROBOTS_WHY}
        unknown = {"count": self.unknown_barcodes_dropped, "reason": _UNKNOWN_WHY,
                   "barcodes": sorted(self.unknown_barcodes)}  # fmt: skip
        dropped = {"robot_sightings": robots, "unknown_barcodes": unknown}
        return {"dataset": self.dataset, "robot": self.robot, "loaded": loaded, "dropped": dropped}

    def lines(self) -> tuple[str, str]:
        """ "loaded: ..." (what was read, with units) and "dropped: ..." (what and why)."""
        unsorted = sum(getattr(self, k) for k in _LOADED if k.endswith("out_of_order"))
        span = self.groundtruth_last_time - self.groundtruth_first_time
        unknown = "".join(f" {b}," for b in sorted(self.unknown_barcodes)).rstrip(",")
        return (
            f"loaded: {self.odometry_rows} odometry rows (largest gap "
            f"{self.odometry_max_gap_s:.3f} s, {self.odometry_duplicate_times} duplicate times), "
            f"{self.measurements_kept} of {self.measurement_rows} measurements, "
            f"{self.groundtruth_rows} ground-truth rows over {span:.1f} s"
            + ("" if self.start_inside_groundtruth else " (the start clamped to it)")
            + (f"; {unsorted} rows out of time order, sorted" if unsorted else ""),
            f"dropped: {self.robot_sightings_dropped} robot sightings ({_ROBOTS_WHY}), "
            f"{self.unknown_barcodes_dropped} sightings of unknown barcodes{unknown} "
            f"({_UNKNOWN_WHY})",
        )

    def summary(self) -> str:
        """A few lines for a terminal: the dataset, what was loaded, what was dropped and why."""
        return "\n  ".join([f"MRCLAM dataset {self.dataset}, robot {self.robot}", *self.lines()])


_LOADED = ("odometry_rows", "odometry_duplicate_times", "odometry_out_of_order", "measurement_rows",
           "measurements_kept", "measurement_out_of_order", "groundtruth_rows",
           "groundtruth_out_of_order", "start_inside_groundtruth")  # fmt: skip
_ROBOTS_WHY, _UNKNOWN_WHY = "other robots, not landmarks", f"not in {BARCODES}"
