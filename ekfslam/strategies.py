"""How a replay decides which landmark each sighting is: `KnownIds` or `HiddenIds`.

`ekfslam.pipeline.replay` takes one of these as its ``association`` and asks it to feed the run
(`Strategy.decide`); the replay itself has no branch for either. With the ids known, the
detections' ids say, and a `ekfslam.core.recovery.Recovery` may watch the updates. With them
hidden, the sightings of each time are associated (nn, jcbb: `ekfslam.core.filter.associating`;
mht: a bank of hypotheses, `ekfslam.core.filter.mht`, whose winner's decisions are replayed), the
decisions perhaps mapped by a filter with other noise (`map_noise`,
`ekfslam.core.filter.mapping`), and the whole run decided again from the last pass's map
(`passes`, `ekfslam.core.filter.prior`).

An `ekfslam.core.association.AssociationConfig` given alone is the strategy it names
(`strategy_of`): ``known`` is `KnownIds()`, any other method `HiddenIds(it)`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ekfslam import checks
from ekfslam.core.association import AssociationConfig
from ekfslam.core.filter.associating import (
    AssociatingFilter,
    AssociationLog,
    shares_image_error,
)
from ekfslam.core.filter.config import MAX_PASSES, FilterConfig
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.filter.mapping import MappingFilter
from ekfslam.core.filter.mht import DecisionReplay, HypothesisBank
from ekfslam.core.filter.prior import PassRecord, pass_record, prior_map, start_with
from ekfslam.core.noise import NoiseConfig
from ekfslam.core.recovery import Recovery, RecoveryConfig
from ekfslam.errors import ConfigError, WrongTypeError
from ekfslam.schedule import KeyframeTaker, Schedule, feed, feed_hidden

#: What one event costs the steps run as Python, against a replay with the ids known, by the
#: association (its work at each time runs in those steps too; ``mht``'s is per hypothesis):
#: the octagon replayed with each, ``FilterConfig(backend="python")``, 2026-12-06: known 88 ms,
#: nn 177 ms, jcbb 403 ms, mht with 8 hypotheses 4,071 ms. A strategy's `work` weighs a run's
#: events by it, for backend "auto" (`ekfslam.core.filter.config.backend_for`): an mht replay of
#: a short run is a long one.
PYTHON_COST = {"known": 1, "nn": 2, "jcbb": 5, "mht": 6}


@dataclass(frozen=True)
class Start:
    """Where a replay's filter starts: the pose (3,) (None: the run's nominal start; the seed
    starts from its nominal pose and recovers the placement error afterwards, eq. 17) and Σ0 of
    eq. (2), (3, 3) (None: zero, the seed's choice)."""

    pose: np.ndarray | None = None
    covariance: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Decided:
    """What a strategy's feeding left: the filter whose state is the result (it recorded the
    history), the association's decisions (None with the ids known), the keyframe taker, the
    times recovery widened the pose, each pass's record and which pass (0, 1, ...) is kept."""

    ekf: EKFSLAM
    log: AssociationLog | None = None
    taker: KeyframeTaker | None = None
    recoveries: tuple[float, ...] = ()
    passes: tuple[PassRecord, ...] = ()
    chosen: int = 0


class Strategy(Protocol):
    """What `ekfslam.pipeline.replay` asks of its ``association``."""

    hidden: bool

    def check(self, config: FilterConfig) -> None:
        """Raise `ConfigError` when this strategy cannot run with `config`."""

    def work(self, steps: Schedule) -> int:
        """The run's events weighed by what this strategy's steps cost (`PYTHON_COST`)."""

    def decide(
        self, start: Start, config: FilterConfig, steps: Schedule, keyframes: int | None
    ) -> Decided:
        """Feed the run to a filter started at `start` and return what it left."""


@dataclass(frozen=True)
class KnownIds:
    """The detections' ids say which landmark each sighting is (the default).

    recovery : widen the pose covariance after a run of rejected sightings
        (`ekfslam.core.recovery`), so a filter that has lost its pose relocalises against its
        map; the times are in the result's ``diagnosis.recoveries``. None (the default): never.
    """

    recovery: RecoveryConfig | None = None
    hidden: bool = field(default=False, init=False, repr=False)

    def __post_init__(self) -> None:
        if self.recovery is not None:
            checks.instance(
                self.recovery, RecoveryConfig, "KnownIds: recovery", "e.g. RecoveryConfig()"
            )

    def check(self, config: FilterConfig) -> None:
        pass

    def work(self, steps: Schedule) -> int:
        return steps.events

    def decide(
        self, start: Start, config: FilterConfig, steps: Schedule, keyframes: int | None
    ) -> Decided:
        ekf = EKFSLAM(start.pose, start.covariance, config)
        fed = ekf if self.recovery is None else Recovery(ekf, self.recovery)
        taker = None if keyframes is None else KeyframeTaker(ekf, steps, keyframes)
        feed(fed, steps, pause=None if taker is None else taker.pause)
        recoveries = () if self.recovery is None else tuple(fed.times)
        return Decided(ekf, taker=taker, recoveries=recoveries)


@dataclass(frozen=True)
class HiddenIds:
    """The ids hidden from the filter: the sightings of each time are associated.

    association : the method and its gates (`ekfslam.core.association.AssociationConfig`;
        ``nn``, ``jcbb`` or ``mht``, not ``known``).
    passes : how many times to decide the whole run (offline: the run is read once per pass).
        Pass k + 1 decides every sighting again, its filter started with pass k's final map as
        prior knowledge (`ekfslam.core.filter.prior`); each pass's decisions are then mapped
        from scratch (by the mapping filter; without `map_noise` by a fresh filter with the
        replay's noise), so no sighting counts twice. The result is the pass whose map fits its
        sightings best (`ekfslam.core.filter.prior.pass_record`'s cost); it stops early at a
        fixed point (no decision changed). 1 (the default): one pass.
    map_noise : decide with the replay's noise and map with this: the decisions are fed as ids
        to a fresh filter with this noise (`ekfslam.core.filter.mapping.MappingFilter`), whose
        state, history and counts the result holds; the association log is the deciding run's.
        None (the default): one filter decides and maps.
    """

    association: AssociationConfig = field(default_factory=lambda: AssociationConfig(method="jcbb"))
    passes: int = 1
    map_noise: NoiseConfig | None = None
    hidden: bool = field(default=True, init=False, repr=False)

    def __post_init__(self) -> None:
        checks.instance(
            self.association,
            AssociationConfig,
            "HiddenIds: association",
            'e.g. AssociationConfig(method="jcbb")',
        )
        if self.association.method == "known":
            raise ConfigError(
                'HiddenIds: association method "known" needs the ids; use KnownIds() for it'
            )
        whole = isinstance(self.passes, int | np.integer) and not isinstance(self.passes, bool)
        if not (whole and 1 <= self.passes <= MAX_PASSES):
            raise ConfigError(
                f"HiddenIds: passes must be a whole number from 1 to {MAX_PASSES}, got "
                f"{checks.shown(self.passes)}"
            )
        if self.map_noise is not None:
            checks.instance(
                self.map_noise,
                NoiseConfig,
                "HiddenIds: map_noise",
                "e.g. NoiseConfig(sigma_x=0.005)",
            )

    def check(self, config: FilterConfig) -> None:
        if self.passes > 1 and config.linearization == "invariant":
            raise ConfigError("passes > 1 needs the standard or FEJ filter, not 'invariant'")

    def work(self, steps: Schedule) -> int:
        cost = PYTHON_COST[self.association.method]
        if self.association.method == "mht":
            cost *= self.association.hypotheses
        mapping = steps.events if self.map_noise is not None else 0
        return steps.events * cost * self.passes + mapping

    def decide(
        self, start: Start, config: FilterConfig, steps: Schedule, keyframes: int | None
    ) -> Decided:
        prior, last, kept = None, None, None
        records: list[PassRecord] = []
        for k in range(self.passes):  # each pass decides again from the last one's map
            ekf, decider, log, taker = self._one_pass(start, config, steps, keyframes, prior)
            if self.passes == 1:
                return Decided(ekf, log, taker)
            records.append(pass_record(ekf.history(), config.gate, log.estimated, last))
            if kept is None or records[-1].cost < records[kept[3]].cost:
                kept = (ekf, log, taker, k)
            if records[-1].changed == 0:
                break  # a fixed point: another pass would decide the same
            prior, last = prior_map(decider), log.estimated
        ekf, log, taker, k = kept
        return Decided(ekf, log, taker, passes=tuple(records), chosen=k)

    def _one_pass(self, start, config, steps, keyframes, prior):
        """One pass: decide every sighting (from `prior`'s map, if given) and, with
        `map_noise`, map the decisions with a fresh filter; with a prior too, with the replay's
        noise if no `map_noise` (the prior holds these sightings already: the map must not get
        them twice). Returns the filter whose state is the result (it records), the deciding
        filter, the decisions and the keyframe taker."""
        pose0, association = start.pose, self.association
        ekf = EKFSLAM(pose0, start.covariance, config)
        mapped = self.map_noise is not None or prior is not None  # the mapping filter records
        decider = EKFSLAM(pose0, start.covariance, config, record=False) if mapped else ekf
        if prior is not None:
            start_with(decider, prior)
        taker = None if keyframes is None else KeyframeTaker(ekf, steps, keyframes)
        pause = None if taker is None else taker.pause
        if association.method == "mht":  # the bank decides, a replay records
            first = EKFSLAM(pose0, start.covariance, config, record=False)
            bank = HypothesisBank(first if prior is None else start_with(first, prior), association)
            feed_hidden(bank, steps)
            _, winner, options = bank.finish()
            associating = DecisionReplay(decider, association, winner, options)
        else:
            associating = AssociatingFilter(decider, association)
        feed_hidden(associating, steps, pause=None if mapped else pause)
        log = associating.finish()
        if mapped:
            shared = shares_image_error(association)  # as it decided
            mapping = MappingFilter(ekf, log, association.time_sigma, shared)
            feed_hidden(mapping, steps.with_noise(self.map_noise or steps.noise), pause=pause)
            mapping.finish()
        return ekf, decider, log, taker


def strategy_of(value: object) -> KnownIds | HiddenIds:
    """`replay`'s ``association`` as a strategy: None is `KnownIds()`, an `AssociationConfig`
    the strategy its method names, a `KnownIds` or `HiddenIds` itself."""
    if value is None:
        return KnownIds()
    if isinstance(value, KnownIds | HiddenIds):
        return value
    if isinstance(value, AssociationConfig):
        return KnownIds() if value.method == "known" else HiddenIds(value)
    raise WrongTypeError(
        "replay: association must be KnownIds(...), HiddenIds(...) or an AssociationConfig, "
        f"got {checks.shown(value)} (e.g. HiddenIds(AssociationConfig(method='jcbb'), passes=2))"
    )
