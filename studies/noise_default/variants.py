"""Variants of a recorded run: the same drive logged the way another robot would log it.

Each takes a `RunLog` and returns a new one; nothing is changed in place. They make the kinds of
log a default must hold on though it was chosen on MRCLAM's own (odometry at about 100 rows a
second, a camera whose sightings come as they were taken):

- `resample_odometry`: the odometry at `hz` rows a second, each row the speed at its time (what a
  slower loop samples), held until the next;
- `hold_speeds`: the speeds held piecewise constant for `seconds` at a time, each piece the speed
  at its start (commands that change once a second);
- `drop_sightings`: a `fraction` of the sightings lost at random (a camera that misses frames);
- `delay_sightings`: every sighting stamped `seconds` late (a camera's latency).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from ekfslam.logs.runlog import Controls, Detections, RunLog


def resample_odometry(run: RunLog, hz: float) -> RunLog:
    """The odometry at `hz` rows a second: the row in force at each tick, held to the next."""
    c = run.controls
    ticks = np.arange(c.t[0], c.t[-1], 1.0 / hz)
    rows = np.searchsorted(c.t, ticks, side="right") - 1
    values = np.asarray(c.values)[rows]
    return dataclasses.replace(run, controls=Controls(t=ticks, kind=c.kind, values=values))


def hold_speeds(run: RunLog, seconds: float) -> RunLog:
    """The speeds held for `seconds` at a time: each piece keeps the row at its start."""
    c = run.controls
    piece = np.floor((np.asarray(c.t) - c.t[0]) / seconds)
    first = np.concatenate([[True], piece[1:] != piece[:-1]])
    return dataclasses.replace(
        run, controls=Controls(t=c.t[first], kind=c.kind, values=np.asarray(c.values)[first])
    )


def drop_sightings(run: RunLog, fraction: float, seed: int = 0) -> RunLog:
    """`fraction` of the sightings dropped at random (seeded)."""
    d = run.detections
    keep = np.random.default_rng(seed).random(len(d.t)) >= fraction
    return dataclasses.replace(
        run,
        detections=Detections(d.t[keep], d.tag_id[keep], d.range[keep], d.bearing[keep]),
    )


def delay_sightings(run: RunLog, seconds: float) -> RunLog:
    """Every sighting stamped `seconds` late."""
    d = run.detections
    return dataclasses.replace(run, detections=dataclasses.replace(d, t=d.t + seconds))


#: The variants the study scores: name -> how to make it.
VARIANTS: dict[str, Callable[[RunLog], RunLog]] = {
    "odometry 8 Hz": lambda run: resample_odometry(run, 8.0),
    "odometry 10 Hz": lambda run: resample_odometry(run, 10.0),
    "held 0.5 s": lambda run: hold_speeds(run, 0.5),
    "held 1 s": lambda run: hold_speeds(run, 1.0),
    "8 Hz, held 1 s": lambda run: hold_speeds(resample_odometry(run, 8.0), 1.0),
    "half the sightings": lambda run: drop_sightings(run, 0.5),
    "sightings 0.2 s late": lambda run: delay_sightings(run, 0.2),
}
