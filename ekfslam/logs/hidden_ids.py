"""What a data source replays with when its ids are hidden from the filter (issue 16), by name.

A run's ``defaults`` name (`ekfslam.logs.runjson.RunMeta.defaults`) picks its loader's tuned
noise (`ekfslam.logs.runjson.TUNED_DEFAULTS`); with the ids hidden a source may need more: a
noise whose Σ is as large as the errors really are (association is a χ² test on Σ), a tighter
one to map the decisions with, and how far its camera's time stamps are off the odometry's.
`HIDDEN_ID_DEFAULTS` holds these per source; a source not listed (the seed's runs, the
simulator's) decides and maps with its ordinary noise, its time stamps exact. The analysis reads
them through `hidden_id_defaults`, so it never names a source.
"""

from __future__ import annotations

from dataclasses import dataclass

from ekfslam.core.noise import NoiseConfig
from ekfslam.logs.mrclam import defaults as mrclam_defaults
from ekfslam.logs.runjson import RunMeta


@dataclass(frozen=True)
class HiddenIdDefaults:
    """One source's replay with hidden ids.

    noise : the deciding filter's. map_noise : the mapping filter's (None: the deciding filter
    maps). time_sigma : s, the camera time stamps' error
    (`ekfslam.core.association.AssociationConfig.time_sigma`). time_shared : one such error per
    image (`AssociationConfig.time_shared`).
    """

    noise: NoiseConfig
    map_noise: NoiseConfig | None
    time_sigma: float
    time_shared: bool


#: By `RunMeta.defaults` name; see `ekfslam.logs.mrclam.defaults` for how each figure was found.
HIDDEN_ID_DEFAULTS: dict[str, HiddenIdDefaults] = {
    mrclam_defaults.NAME: HiddenIdDefaults(
        noise=mrclam_defaults.MRCLAM_CONSISTENT_NOISE,
        map_noise=mrclam_defaults.MRCLAM_MAP_NOISE,
        time_sigma=mrclam_defaults.MRCLAM_TIME_SIGMA,
        time_shared=mrclam_defaults.MRCLAM_TIME_SHARED,
    ),
}


def hidden_id_defaults(meta: RunMeta) -> HiddenIdDefaults | None:
    """The run's source's `HiddenIdDefaults`, or None (its ordinary noise, exact time stamps)."""
    return None if meta.defaults is None else HIDDEN_ID_DEFAULTS.get(meta.defaults)
