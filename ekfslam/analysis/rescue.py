"""The innovations' log-likelihood of a replay, and the default noise's rescue.

For the true R and Q the innovations ν = z - ẑ (eq. 13) of a replay are zero-mean Gaussians with
covariance S (eq. 15) given everything before them, so a log's likelihood is the product of their
densities (the prediction-error decomposition; Mehra 1972; Bar-Shalom, Li & Kirubarajan 2001,
§5.4 and §11.2). With a gate, a rejected sighting is known only to lie beyond it: it counts by
that probability, e^(-gate/2) for 2 dof, never by its value (a censored observation), and from the
start of a lost stretch (`ekfslam.core.diagnosis.Diagnosis.lost_after`) every sighting counts so,
the few still accepted included:

    ln L(R, Q) = Σ_accepted -½ (νᵀ S⁻¹ ν + ln det 2πS) + Σ_censored -gate / 2

`ekfslam.analysis.noise_fit` maximises it over R and Q. Here it picks among a few candidates:

**The default's rescue** (`replay_rescued`, what ``run`` and ``score-mrclam`` do by default). A
documented default is a density per second measured on logs like the ones it was chosen on; a
log of another kind (odometry at 8 Hz instead of 100, speeds held for a second at a time) may
need more motion noise, and with too little the filter is lost. So a replay with the documented
noise whose diagnosis is not ok is replayed again with R scaled by 2, 4, 8 and 16
(`RESCUE_SCALES`), and the scale whose innovations are most likely (the same censored ln L) is
kept: a handful of replays, only for a log the default does not fit. If that replay still holds
a misplaced landmark (placed while the pose was off, every later sighting of it rejected) and
the filter does not re-initialise landmarks (MRCLAM's does not), it is tried once more with
re-initialisation, kept if more likely. A replay that is ok is never touched. Measured on
MRCLAM Datasets 1, 2, 4 and 7 and their variants (``python -m studies.noise_default.study
defaults``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ekfslam import pipeline
from ekfslam.core.diagnosis import Diagnosis
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.history import History, Outcome
from ekfslam.core.noise import NoiseConfig
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import ReplayResult

Array = NDArray[np.float64]
_LN_2PI = math.log(2 * math.pi)


def sighting_log_likelihoods(
    history: History, gate: float | None, lost_after: float | None = None
) -> Array:
    """Each sighting's term of ln L (see the module), (M,), 0 for those no innovation tests.

    gate : the filter's NIS gate (None: off, nothing is censored). lost_after : s from the
    history's first event; from there on every tested sighting counts as censored (None: no
    lost stretch).
    """
    outcome = np.asarray(history.obs_outcome)
    nu = np.asarray(history.obs_innovation, dtype=float)
    S = np.asarray(history.obs_S, dtype=float)
    terms = np.zeros(len(outcome))
    accepted = outcome == Outcome.ACCEPTED
    censored = np.isin(outcome, (Outcome.REJECTED, Outcome.REINITIALISED, Outcome.SINGULAR))
    if lost_after is not None:
        late = np.asarray(history.obs_t) - history.t[0] >= lost_after
        censored |= accepted & late
        accepted &= ~late
    a, b, c = S[accepted, 0, 0], S[accepted, 0, 1], S[accepted, 1, 1]
    det = a * c - b * b
    n0, n1 = nu[accepted, 0], nu[accepted, 1]
    nis = (c * n0 * n0 - 2 * b * n0 * n1 + a * n1 * n1) / det
    with np.errstate(divide="ignore", invalid="ignore"):
        dense = -0.5 * (nis + np.log(det)) - _LN_2PI
    terms[accepted] = np.where(np.isfinite(dense) & (det > 0), dense, -0.5 * (gate or 1e3))
    terms[censored] = -0.5 * (gate if gate is not None else 1e3)
    return terms


#: The factors on σx, σy and σθ (R times their squares) a rescue tries after the documented
#: noise.
RESCUE_SCALES = (2.0, 4.0, 8.0, 16.0)


def log_likelihood(result: ReplayResult) -> float:
    """ln L per sighting of a replay (`sighting_log_likelihoods` with its gate and lost
    stretch); -inf when it has no sighting."""
    lost = None if result.diagnosis is None else result.diagnosis.lost_after
    terms = sighting_log_likelihoods(result.history, result.config.gate, lost)
    return float(terms.sum() / len(terms)) if len(terms) else -math.inf


def scaled_motion(noise: NoiseConfig, factor: float) -> NoiseConfig:
    """`noise` with σx, σy and σθ times `factor` (R, per second, times its square)."""
    return dataclasses.replace(
        noise,
        sigma_x=noise.sigma_x * factor,
        sigma_y=noise.sigma_y * factor,
        sigma_theta=noise.sigma_theta * factor,
    )


#: A rescue whose most likely replay still holds a misplaced landmark (the diagnosis's
#: `misplaced`) tries it again re-initialising landmarks after this many agreeing rejections
#: (`FilterConfig.reinit_after`), when the config does not already.
RESCUE_REINIT_AFTER = 3


@dataclass(frozen=True, eq=False)
class Rescue:
    """A replay with the documented noise, or, when that one was not ok, the most likely of it
    with R scaled, and re-initialising a misplaced landmark (`replay_rescued`).

    result : the replay kept; its noise is ``result.noise``, its config ``result.config``.
    scale : the factor on σx, σy, σθ kept (1.0: the documented noise). reinitialise : whether
    the kept replay re-initialises landmarks where the documented config did not.
    documented : the documented noise's diagnosis. tried : (what, ln L per sighting, verdict) of
    each replay made, the documented first ("x1", "x4", "x4 + re-init").
    """

    result: ReplayResult
    scale: float
    documented: Diagnosis
    tried: tuple[tuple[str, float, str], ...]
    reinitialise: bool = False

    @property
    def rescued(self) -> bool:
        return self.scale != 1.0 or self.reinitialise

    def line(self) -> str | None:
        """What ``run`` prints when the noise was rescued (None when it was not tried)."""
        if len(self.tried) == 1:
            return None
        tried = ", ".join(f"{what} {v}" for what, _, v in self.tried)
        if not self.rescued:
            return (
                f"noise: the documented noise is {self.documented.verdict}; R scaled ({tried}) "
                "was no more likely: kept"
            )
        kept = f"R x {self.scale:g}" + (
            f", re-initialising landmarks (after {RESCUE_REINIT_AFTER})"
            if self.reinitialise
            else ""
        )
        return (
            f"noise: the documented noise was {self.documented.verdict} "
            f"({self.documented.reasons[0]}); replayed with {kept}, the most likely of {tried}"
        )

    def as_dict(self) -> dict:
        return {
            "scale": self.scale,
            "reinitialise": self.reinitialise,
            "documented_verdict": self.documented.verdict,
            "documented_reasons": list(self.documented.reasons),
            "tried": [
                {"replay": what, "log_likelihood": ll, "verdict": v} for what, ll, v in self.tried
            ],
        }


def replay_rescued(
    run: RunLog, noise: NoiseConfig, config: FilterConfig, **kwargs: object
) -> Rescue:
    """`replay` with `noise`; if its diagnosis is not ok, again with R times each of
    `RESCUE_SCALES`, keeping the most likely; if that one still holds a misplaced landmark and
    `config` does not re-initialise landmarks, once more re-initialising them
    (`RESCUE_REINIT_AFTER`), kept if more likely (see the module). `kwargs` go to every `replay`
    (keyframes, start, association=KnownIds(recovery=...)); hidden ids are not rescued (pass
    them to `replay`)."""
    # looked up at the call: a test may replace `pipeline.replay`
    first = pipeline.replay(run, noise, config, **kwargs)
    assert first.diagnosis is not None  # every replay has one
    tried = [("x1", log_likelihood(first), first.diagnosis.verdict)]
    if first.diagnosis.ok or noise.R_per_step is not None:
        return Rescue(first, 1.0, first.diagnosis, tuple(tried))
    best, best_scale, best_ll = first, 1.0, tried[0][1]
    # the rescue's replays together choose the backend
    batch = pipeline.batch_config(run, len(RESCUE_SCALES) + 1, config)
    for factor in RESCUE_SCALES:
        result = pipeline.replay(run, scaled_motion(noise, factor), batch, **kwargs)
        tried.append((f"x{factor:g}", log_likelihood(result), result.diagnosis.verdict))
        if tried[-1][1] > best_ll:
            best, best_scale, best_ll = result, factor, tried[-1][1]
    reinit = False
    if best.diagnosis.misplaced and batch.reinit_after is None:
        again = dataclasses.replace(batch, reinit_after=RESCUE_REINIT_AFTER)
        result = pipeline.replay(run, best.noise, again, **kwargs)
        tried.append(
            (f"x{best_scale:g} + re-init", log_likelihood(result), result.diagnosis.verdict)
        )
        if tried[-1][1] > best_ll:
            best, reinit = result, True
    return Rescue(best, best_scale, first.diagnosis, tuple(tried), reinit)
