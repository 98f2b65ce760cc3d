"""``--association auto``: a cheap association first, a costlier one only where the map is not
to be trusted (issue 39).

With the ids hidden no method is right everywhere: on MRCLAM JCBB maps Dataset 7's robots within
1.2-1.5x of the barcodes' map in 0.3-3 s each, and three robots of Dataset 1 at 10-50x; a bank
of hypotheses (``mht``) maps nearly all of them within 1.5x, at 5-35 s a robot. So `replay_auto`
does what `ekfslam.analysis.rescue.replay_rescued` does for the noise: it replays with `FIRST`
and reads its diagnosis (`ekfslam.core.diagnosis`, which with hidden ids also counts landmarks
founded late, duplicates, sightings dropped as ambiguous and a few percent beyond the χ² bound:
`ekfslam.core.diagnosis.ASSOCIATION_THRESHOLDS`). An ok replay is kept as it is. One that is not
is replayed by `ESCALATION`, and the escalated replay is kept unless its diagnosis is worse
(ok, suspect, lost) than the first's. What was tried, and why, is in `AutoAssociation.line`.

Which escalation, and the thresholds it is asked at, were chosen on every robot of MRCLAM
Datasets 1, 2, 4 and 7, leaving one dataset out (``python -m studies association-auto``; the
table is docs/studies/association-auto.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from ekfslam import pipeline
from ekfslam.analysis import association as assoc
from ekfslam.core.diagnosis import VERDICTS
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.noise import NoiseConfig, default_config
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import ReplayResult
from ekfslam.strategies import HiddenIds


@dataclass(frozen=True)
class Strategy:
    """One way of deciding: an association `method`, how many `passes`
    (`ekfslam.pipeline.replay`), and ``mht``'s bank size (None: its default)."""

    method: str
    passes: int = 1
    hypotheses: int | None = None

    @property
    def name(self) -> str:
        """As the options say it: ``jcbb``, ``jcbb --passes 2``, ``mht --hypotheses 3``."""
        extra = f" --passes {self.passes}" if self.passes > 1 else ""
        if self.hypotheses is not None:
            extra += f" --hypotheses {self.hypotheses}"
        return self.method + extra


#: The cheap first replay, and what a replay whose diagnosis is not ok is replayed with.
FIRST = Strategy("jcbb")
ESCALATION = Strategy("mht")


@dataclass(frozen=True)
class Tried:
    """One replay auto made: its strategy, verdict, reasons and filter seconds."""

    strategy: Strategy
    verdict: str
    reasons: tuple[str, ...]
    seconds: float

    def as_dict(self) -> dict:
        return {
            "association": self.strategy.name,
            "verdict": self.verdict,
            "reasons": list(self.reasons),
            "seconds": self.seconds,
        }


@dataclass(frozen=True, eq=False)
class AutoAssociation:
    """What `replay_auto` kept and what it tried.

    result : the replay kept (its ``association`` log names the method). strategy : how it
    decided. tried : each replay made, the first first. seconds : every replay's filter time.
    """

    result: ReplayResult
    strategy: Strategy
    tried: tuple[Tried, ...]

    @property
    def escalated(self) -> bool:
        return len(self.tried) > 1

    @property
    def seconds(self) -> float:
        return sum(t.seconds for t in self.tried)

    def line(self) -> str:
        """One line for ``run``: which association was used, and why."""
        first = self.tried[0]
        if not self.escalated:
            return f"association: auto used {first.strategy.name} (its diagnosis is ok)"
        second = self.tried[1]
        why = f"{first.strategy.name} was {first.verdict} ({first.reasons[0]})"
        if self.strategy == second.strategy:
            return (
                f"association: auto used {second.strategy.name}, {second.verdict}: {why}; "
                f"{self.seconds:.1f} s in all"
            )
        return (
            f"association: auto kept {first.strategy.name}: {why}, and "
            f"{second.strategy.name} was {second.verdict}, no better"
        )

    def as_dict(self) -> dict:
        return {
            "used": self.strategy.name,
            "escalated": self.escalated,
            "tried": [t.as_dict() for t in self.tried],
            "seconds": self.seconds,
        }


def _tried(strategy: Strategy, result: ReplayResult) -> Tried:
    d = result.diagnosis
    assert d is not None  # every replay has one
    return Tried(strategy, d.verdict, d.reasons, result.seconds)


def replay_auto(
    run: RunLog,
    noise: NoiseConfig | None = None,
    config: FilterConfig | None = None,
    *,
    map_noise: NoiseConfig | str | None = "source",
    time_shared: bool | None = None,
    first: Strategy = FIRST,
    escalation: Strategy = ESCALATION,
    **kwargs: object,
) -> AutoAssociation:
    """`replay` with the ids hidden by `first`; when its diagnosis is not ok, again by
    `escalation`, kept unless its diagnosis is worse (see the module).

    noise : the deciding filter's (default `ekfslam.analysis.association.association_noise`).
    config : the filter's (default `default_config(run)`). map_noise : the mapping filter's
    ("source": `ekfslam.analysis.association.association_map_noise`; None: the deciding
    filter maps). time_shared : `ekfslam.analysis.association.association_config`'s. `kwargs`
    go to every `replay` (keyframes, start).
    """
    noise = noise or assoc.association_noise(run)
    config = config or default_config(run)
    mapping = assoc.association_map_noise(run) if map_noise == "source" else map_noise

    def play(strategy: Strategy) -> ReplayResult:
        association = assoc.association_config(
            run, strategy.method, strategy.hypotheses, time_shared
        )
        hidden = HiddenIds(association, passes=strategy.passes, map_noise=mapping)
        # looked up at the call: a test may replace `pipeline.replay`
        return pipeline.replay(run, noise, config, association=hidden, **kwargs)

    result = play(first)
    tried = [_tried(first, result)]
    if tried[0].verdict == "ok":
        return AutoAssociation(result, first, tuple(tried))
    again = play(escalation)
    tried.append(_tried(escalation, again))
    if VERDICTS.index(tried[1].verdict) <= VERDICTS.index(tried[0].verdict):
        return AutoAssociation(again, escalation, tuple(tried))
    return AutoAssociation(result, first, tuple(tried))
