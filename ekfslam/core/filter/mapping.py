"""Decide with one filter, map with another: a deciding run's decisions fed to a second EKF as ids.

Association is a χ² test on Σ, so the filter that decides needs a noise whose Σ is as large as
the errors really are (on MRCLAM, `ekfslam.logs.mrclam.defaults.MRCLAM_CONSISTENT_NOISE`); but
its wide motion noise lets the pose wander between corrections and costs the map. `MappingFilter`
takes the decisions of a finished run (`ekfslam.core.filter.associating.AssociationLog`: each
sighting's estimated landmark id) and feeds them, as ids, to a fresh `EKFSLAM` built with a
*mapping* noise: the same updates of eqs. (13)-(16) in the same order (within one time the
sightings paired with a mapped landmark first, then those that confirmed a new one, as
`AssociatingFilter._apply` does), each with the per-sighting Q the deciding filter used, the
time-stamp term included (`AssociatingFilter.noises`: (ω · time_sigma)² on the bearing, or with
``time_shared`` each sighting's share of the image's one error, `shared_sighting_noise`).
Tentative and ambiguous sightings are not used, as they were not by the deciding filter.

It is driven like an `AssociatingFilter` (``predict_many``, ``observe``, ``finish``), so the replay
walks it over the same schedule (`ekfslam.pipeline.replay`'s ``map_noise``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter.associating import ASSOCIATED, CONFIRMED, AssociationLog
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter_checks import check_observe
from ekfslam.core.timestamp import TimeError, image_noises

Array = NDArray[np.float64]


class MappingFilter:
    """An `EKFSLAM` fed another run's decisions as ids (see the module).

    Parameters
    ----------
    ekf : the mapping filter (built with the mapping noise's run; its ids become the estimated).
    log : the deciding run's decisions, one per sighting in the order they will be fed.
    time_sigma : s, `AssociationConfig.time_sigma` of the deciding run (0: no time-stamp term).
    time_shared : whether the deciding run shared the image's one time-stamp error
        (`ekfslam.core.filter.associating.shares_image_error`; each sighting's share of it,
        `ekfslam.core.timestamp.shared_sighting_noise`).
    """

    def __init__(
        self, ekf: EKFSLAM, log: AssociationLog, time_sigma: float = 0.0, time_shared: bool = False
    ) -> None:
        self.ekf = ekf
        self.log = log
        self.time_sigma = float(time_sigma)
        self.time_shared = bool(time_shared)
        self._next = 0  # the first sighting not yet fed

    def predict_many(self, us, dts, ts, M=None, R=None, *, validate: bool = True) -> None:
        """`EKFSLAM.predict_many` of the mapping filter."""
        self.ekf.predict_many(us, dts, ts, M, R, validate=validate)

    def observe(
        self,
        zs: ArrayLike,
        Q: ArrayLike,
        t: float,
        omega: float = 0.0,
        velocity: tuple[float, float] = (0.0, 0.0),
    ) -> list[int]:
        """Feed the sightings of time t (s) under the ids the deciding run gave them."""
        check_observe(zs, Q, t, "MappingFilter.observe")  # once: then fed unchecked
        zs = np.asarray(zs, dtype=float).reshape(-1, 2)
        k, m = self._next, len(zs)
        if k + m > len(self.log.estimated):
            raise ValueError(f"{len(self.log.estimated)} decisions for more sightings ({k + m})")
        rate, error = (
            (velocity[0], velocity[1], omega),
            TimeError(self.time_sigma, self.time_shared),
        )
        _, Qs, _ = image_noises(Q, zs, rate, error, self.ekf.sensor)
        Qs = np.broadcast_to(Qs, (m, 2, 2))
        used = self.log.estimated[k : k + m].tolist()
        what = self.log.decision[k : k + m]
        for kind in (ASSOCIATED, CONFIRMED):  # the deciding filter's order (`_apply`)
            for i in range(m):
                if what[i] == kind and used[i] >= 0:
                    self.ekf.update(used[i], zs[i], Qs[i], t, validate=False)
        self._next = k + m
        return used

    def finish(self) -> AssociationLog:
        """The deciding run's log (every decision must have been fed)."""
        if self._next != len(self.log.estimated):
            raise ValueError(
                f"{len(self.log.estimated)} decisions, {self._next} sightings fed: the mapping "
                "replay is not the deciding run's schedule"
            )
        return self.log
