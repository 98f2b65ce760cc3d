"""R and Q from the log itself, with no ground truth: maximum likelihood of the innovations.

The seed chose its noise "by measuring the errors ... then fine-tune". A log already holds what
that needs: every sighting of a mapped landmark is a prediction the filter made and the data
checked. For the true R and Q the innovations ν = z - ẑ (eq. 13) are zero-mean Gaussians with
covariance S (eq. 15) given everything before them, so the log's likelihood is the product of
their densities (the prediction-error decomposition; Mehra 1972 and Bar-Shalom, Li & Kirubarajan
2001, §11.2 and §5.4 on innovation-based noise identification):

    ln L(R, Q) = Σ_accepted -½ (νᵀ S⁻¹ ν + ln det 2πS) + Σ_rejected ln P(NIS > gate)

`fit_noise` maximises it over the log of a few σ with `scipy.optimize.minimize` (Nelder-Mead: the
gate makes the function step where a sighting flips between accepted and rejected, so no
gradient), after scaling every σ of the start by one factor (`SCALES`: a start 100 times too
small sits in a flat, lost region, or the search ends beside a local optimum where R is so wide
that Q no longer matters), each evaluation a full replay (`ekfslam.pipeline.replay`, about
0.05-0.2 s for a MRCLAM robot). What it must not learn from, and how it does not:

- a sighting the gate rejects counts only as "beyond the gate", its probability under the
  model, e^(-gate/2) for 2 dof, never by its value: a censored observation. A noise that rejects
  what it cannot explain pays that price for each, so shrinking Q until only the easy sightings
  pass does not pay;
- a lost stretch (`ekfslam.core.diagnosis.Diagnosis.lost_after`: from there on most sightings
  are rejected) counts every sighting as censored, the few it still accepts included: their
  innovations come from a filter that no longer knows where it is.

R is fitted as the control-increment density M of `NoiseConfig` (σx, σθ per √s, and σy when the
controls ever move sideways: a differential drive's σy keeps its start value, nothing in its log
tells sideways slip apart from σx); Q as σr and σφ. The uncertainty of each fitted ln σ is from
the outer product of the per-sighting scores (BHHH: the innovations of the right model are a
martingale difference sequence), by central differences, two replays per σ; it assumes the
errors are white, so read it as a lower bound.

**Errors that are not white.** The likelihood is that of white errors. A real sensor's are not:
MRCLAM's ranges read a landmark 0.3 m short for seconds at a time, and the range innovations of
a landmark's consecutive sightings correlate at ρ = 0.77-0.92 (bearings: 0.07-0.12). The fit
then finds σr = 0.07-0.12 m, what one sighting's error is, and the filter weighs ten sightings
of one biased stretch as ten independent ones: the maps are 0.08-0.10 m, against 0.06-0.08 m
with the hand-tuned σr = 0.3 m. An error that persists with lag-one correlation ρ (AR(1)) adds
(1 + ρ) / (1 - ρ) times its variance to a mean of many sightings: its long-run variance. So
`fit_noise` measures ρ for range and bearing from the fitted replay's innovations (consecutive
accepted sightings of the same landmark, at most `CORRELATION_GAP` apart) and widens σr and σφ
by √((1 + ρ) / (1 - ρ)) (ρ > 0 only): on Dataset 7 robot 1 σr 0.12 -> 0.34 m (the hand-tuned
default's 0.3, found from the log alone) and the map 0.082 -> 0.050 m. `NoiseFit.white` keeps
the white fit.

**The fit against the default it started from** (`fit_from_default`, what ``fit-noise`` and
``run --noise fit`` keep). The fit is kept only when the diagnosis calls its replay no worse and
it predicts the data better, judged on the default's own ground: `predictive_gain`, each
replay's log predictive density -½(νᵀS⁻¹ν + ln det 2πS) of the sightings the default accepted
(the fit's too where its gate rejected one: a prediction it made), paired, their mean
difference, and its standard error by batch means (`GAIN_BATCHES` stretches of consecutive
sightings: the differences are correlated for seconds, as the errors are). The fit is kept when
that gain exceeds `GAIN_Z` standard errors. ln L per sighting, what the search maximises, is no
fair judge between two replays: which sightings each censors depends on its own S, and a
censored sighting's term is a probability while an accepted one's is a density (in units of the
measurement: change metres for centimetres and the two shift against each other). On MRCLAM
Dataset 4 robot 1 the fit was kept by ln L (2.762 against 2.653 per sighting) and mapped at
0.055 m against the default's 0.043 m: its gain came from the 3% of sightings the default
rejected, and on the sightings the default accepted it predicted +0.015 ± 0.020 better per
sighting, no evidence (``python -m studies noise-fit``).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import minimize

from ekfslam.analysis.rescue import (
    Rescue,
    log_likelihood,
    replay_rescued,
    sighting_log_likelihoods,
)
from ekfslam.core.diagnosis import VERDICTS, Diagnosis
from ekfslam.core.filter.config import FilterConfig
from ekfslam.core.filter.history import History, Outcome
from ekfslam.core.noise import NoiseConfig, default_config, default_noise
from ekfslam.errors import ConfigError, EkfSlamError
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import ReplayResult, batch_config, replay

Array = NDArray[np.float64]

#: The σ `fit_noise` fits (and sigma_y when the controls move sideways), and their units.
FITTED = ("sigma_x", "sigma_theta", "sigma_range", "sigma_bearing")
UNITS = {
    "sigma_x": "m/√s",
    "sigma_y": "m/√s",
    "sigma_theta": "rad/√s",
    "sigma_range": "m",
    "sigma_bearing": "rad",
}
#: Where the search may go, σ in the NoiseConfig's units: beyond, every pose is swamped or S is
#: numerically singular.
BOUNDS = (1e-5, 10.0)
#: The first simplex spans a factor e^0.7 ≈ 2 on each σ; the search stops when its points are
#: within 5% of each other and their mean log-likelihood per sighting within 1e-3 (the widening
#: for correlated errors moves σr by factors of 3: finer is not worth the replays).
SIMPLEX_STEP = 0.7
X_TOLERANCE = 0.05
F_TOLERANCE = 1e-3
#: s. Consecutive sightings of one landmark at most this far apart enter the correlation.
CORRELATION_GAP = 2.0
#: The widening's ρ is at most this: (1 + ρ) / (1 - ρ) <= 39, σ by at most 6.2 times.
MAX_CORRELATION = 0.95
#: Before the search, every σ of the start is scaled by 10^k for each k here, and the search
#: starts from the best (a start 100 times too small is found 100 times too small).
SCALES = (-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0)
#: ln σ step of the central differences for the standard errors.
SCORE_STEP = 0.05
#: A standard error of ln σ beyond this (a factor e² either way) says the log does not
#: determine that σ.
UNDETERMINED = 2.0
#: `predictive_gain`'s batches of consecutive sightings (batch means: 20 batches give the
#: standard error to within about 16%), and how many of its standard errors the fit's gain must
#: exceed to be kept (one-sided, about 97.5%).
GAIN_BATCHES = 20
GAIN_Z = 2.0
_LN_2PI = math.log(2 * math.pi)


@dataclass(frozen=True, eq=False)
class NoiseFit:
    """What `fit_noise` found.

    noise : the fitted NoiseConfig, σr and σφ widened for correlated errors (see the module).
    white : the maximum-likelihood fit itself (errors taken as white). start : where the search
        began. fields : the σ fitted.
    correlation : (ρ range, ρ bearing), the lag-one correlation of a landmark's consecutive
        innovations in the white fit's replay (NaN: too few pairs).
    standard_errors : {field: standard error of ln σ} of the white fit (σ is uncertain by a
        factor e^±se); NaN where the scores did not determine it.
    log_likelihood, start_log_likelihood : ln L per tested sighting at the white fit and at the
        start.
    sightings : the tested sightings (accepted, rejected or re-initialised) of the white fit.
    evaluations : replays made, the standard errors' and the last one's included.
    seconds : wall time.
    result : the replay with `noise`; result.diagnosis is the NIS check.
    """

    noise: NoiseConfig
    white: NoiseConfig
    start: NoiseConfig
    fields: tuple[str, ...]
    correlation: tuple[float, float]
    standard_errors: dict[str, float]
    log_likelihood: float
    start_log_likelihood: float
    sightings: int
    evaluations: int
    seconds: float
    result: ReplayResult

    @property
    def diagnosis(self) -> Diagnosis:
        assert self.result.diagnosis is not None  # every replay has one
        return self.result.diagnosis

    def lines(self) -> list[str]:
        """What ``fit-noise`` prints: R, Q with their uncertainty, and the NIS check."""
        n, w = self.noise, self.white

        def sigma(name: str) -> str:
            se = self.standard_errors.get(name, math.nan)
            if name not in self.fields:
                spread = " (kept: not seen apart from sigma_x)"
            elif not math.isfinite(se) or se > UNDETERMINED:
                spread = " (not determined by this log)"
            else:
                spread = f" (±{100 * math.expm1(se):.0f}%)"
            return f"{name} {getattr(n, name):.4g} {UNITS[name]}{spread}"

        d = self.diagnosis
        nis = "none" if d.nis_mean is None else f"{d.nis_mean:.2f}"
        rho_r, rho_b = self.correlation
        return [
            f"R (motion, per second of driving): {sigma('sigma_x')}, {sigma('sigma_y')}, "
            f"{sigma('sigma_theta')}",
            f"Q (each sighting): {sigma('sigma_range')}, {sigma('sigma_bearing')}",
            f"  white errors would give sigma_range {w.sigma_range:.4g} m, sigma_bearing "
            f"{w.sigma_bearing:.4g} rad; a landmark's consecutive innovations correlate at "
            f"{rho_r:.2f} (range) and {rho_b:.2f} (bearing): each sigma with rho > 0 is "
            f"widened by sqrt((1 + rho) / (1 - rho))",
            f"log-likelihood per sighting {self.log_likelihood:.3f} (start: "
            f"{self.start_log_likelihood:.3f}), {self.sightings} sightings, "
            f"{self.evaluations} replays in {self.seconds:.1f} s, no ground truth used",
            f"NIS check with it: mean {nis} capped at 9.21 (consistent: 1.98), "
            f"{100 * d.outlier_share:.1f}% beyond the chi2 99% bound (consistent: 1%), "
            f"diagnosis {d.verdict}",
        ]

    def as_dict(self) -> dict:
        """The JSON form (``fit-noise --json``, ``run --noise fit --json``'s ``noise_fit``)."""

        def sigmas(noise: NoiseConfig) -> dict:
            return {name: getattr(noise, name) for name in UNITS}

        def number(x: float) -> float | None:
            return x if math.isfinite(x) else None

        return {
            "noise": sigmas(self.noise),
            "white": sigmas(self.white),
            "start": sigmas(self.start),
            "fitted": list(self.fields),
            "correlation": {
                "range": number(self.correlation[0]),
                "bearing": number(self.correlation[1]),
            },
            "standard_error_of_log_sigma": {k: number(v) for k, v in self.standard_errors.items()},
            "log_likelihood_per_sighting": self.log_likelihood,
            "start_log_likelihood_per_sighting": self.start_log_likelihood,
            "sightings": self.sightings,
            "evaluations": self.evaluations,
            "seconds": self.seconds,
            "nis_check": self.diagnosis.as_dict(),
        }


def fit_noise(
    run: RunLog,
    start: NoiseConfig | None = None,
    config: FilterConfig | None = None,
    *,
    max_evaluations: int = 200,
) -> NoiseFit:
    """Fit R (σx, σθ; σy when the robot moves sideways) and Q (σr, σφ) to the run's innovations
    by maximum likelihood, then widen Q for correlated errors (see the module).

    start : where the search begins (default `default_noise(run)`); its R_per_step must be None
        (a fixed per-step R has no density to fit). config : the filter's choices, its gate
        included (default `default_config(run)`). max_evaluations : replays the search may make.
    """
    start = start or default_noise(run)
    config = config or default_config(run)
    if start.R_per_step is not None:
        raise ConfigError(
            "fit_noise fits the motion density M: start from a NoiseConfig without R_per_step"
        )
    began = time.perf_counter()
    sideways = bool(np.any(np.asarray(run.control_twist())[:, 1] != 0))
    fields = (*FITTED[:1], "sigma_y", *FITTED[1:]) if sideways else FITTED
    config = batch_config(run, max_evaluations, config)  # the search's replays together
    cost = _Cost(run, start, config, fields)
    x_start = np.log([max(getattr(start, f), BOUNDS[0]) for f in fields])
    # a start 100 times off leaves the simplex in a flat lost region or beside a local optimum
    # (R so wide that Q does not matter): first every σ scaled by one factor, the best taken
    x0 = min((x_start + math.log(10) * k for k in SCALES), key=cost)
    simplex = np.vstack([x0, x0 + SIMPLEX_STEP * np.eye(len(x0))])
    found = minimize(
        cost,
        x0,
        method="Nelder-Mead",
        options={
            "initial_simplex": simplex,
            "xatol": X_TOLERANCE,
            "fatol": F_TOLERANCE,
            "maxfev": max_evaluations,
        },
    )
    best = found.x if found.fun <= cost(x0) else x0
    white = cost.noise(best)
    errors = _standard_errors(cost, best)
    white_result = replay(run, white, config)
    rho = innovation_correlation(white_result.history, CORRELATION_GAP)
    noise = widened(white, rho)
    result = replay(run, noise, config)
    tested = int(np.count_nonzero(np.isin(white_result.history.obs_outcome, _TESTED)))
    return NoiseFit(
        noise=noise,
        white=white,
        start=start,
        fields=fields,
        correlation=rho,
        standard_errors=errors,
        log_likelihood=-cost(best),
        start_log_likelihood=-cost(x_start),
        sightings=tested,
        evaluations=cost.calls + 2,
        seconds=time.perf_counter() - began,
        result=result,
    )


@dataclass(frozen=True)
class Gain:
    """How much better one replay predicts the sightings another accepted (`predictive_gain`).

    mean : the mean difference of the log predictive densities per sighting (NaN: none to
    compare; -inf: a density the second replay could not give). standard_error : of the mean,
    by batch means (NaN: too few sightings). sightings : how many were compared.
    """

    mean: float
    standard_error: float
    sightings: int

    @property
    def significant(self) -> bool:
        """Above `GAIN_Z` standard errors (False for NaN)."""
        return bool(self.mean > GAIN_Z * self.standard_error)

    def text(self) -> str:
        return f"{self.mean:+.3f} ± {self.standard_error:.3f} per sighting over {self.sightings}"

    def as_dict(self) -> dict:
        def number(x: float) -> float | None:
            return x if math.isfinite(x) else None

        return {
            "mean": number(self.mean),
            "standard_error": number(self.standard_error),
            "sightings": self.sightings,
        }


def log_predictive_densities(history: History) -> Array:
    """-½(νᵀS⁻¹ν + ln det 2πS) of every sighting row (M,), ν of eq. (13) and S of eq. (15) as
    the filter predicted them, whatever its gate did next (NaN where S is not positive definite
    or the row holds no prediction)."""
    nu = np.asarray(history.obs_innovation, dtype=float)
    S = np.asarray(history.obs_S, dtype=float)
    a, b, c = S[:, 0, 0], S[:, 0, 1], S[:, 1, 1]
    det = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        nis = (c * nu[:, 0] ** 2 - 2 * b * nu[:, 0] * nu[:, 1] + a * nu[:, 1] ** 2) / det
        dense = -0.5 * (nis + np.log(det)) - _LN_2PI
    return np.where((a > 0) & (det > 0) & np.isfinite(dense), dense, np.nan)


def predictive_gain(default: ReplayResult, fit: ReplayResult) -> Gain:
    """How much better `fit` predicts the sightings `default` accepted (before its lost
    stretch, if any) than `default` did: the paired log predictive densities (`fit`'s where its
    gate rejected the sighting too), their mean difference and its batch-means standard error
    over `GAIN_BATCHES` stretches of consecutive sightings (see the module). Both must be
    replays of one run (the same sightings in the same order)."""
    hd, hf = default.history, fit.history
    td, tf = np.asarray(hd.obs_t), np.asarray(hf.obs_t)
    if td.shape != tf.shape or not np.array_equal(td, tf):
        raise ValueError(
            f"predictive_gain compares replays of one run: {len(td)} and {len(tf)} sightings, "
            "not the same"
        )
    mine = np.asarray(hd.obs_outcome) == Outcome.ACCEPTED
    lost = None if default.diagnosis is None else default.diagnosis.lost_after
    if lost is not None:
        mine &= td - hd.t[0] < lost
    dd, df = log_predictive_densities(hd)[mine], log_predictive_densities(hf)[mine]
    keep = np.isfinite(dd)  # an accepted sighting has a density; a degenerate S is left out
    dd, df = dd[keep], df[keep]
    n = len(dd)
    if n == 0:
        return Gain(math.nan, math.nan, 0)
    if not np.all(np.isfinite(df)):
        return Gain(-math.inf, math.nan, n)
    diff = df - dd
    k = min(GAIN_BATCHES, n)
    means = np.array([part.mean() for part in np.array_split(diff, k)])
    se = float(means.std(ddof=1) / math.sqrt(k)) if k > 1 else math.nan
    return Gain(float(diff.mean()), se, n)


@dataclass(frozen=True, eq=False)
class FitChoice:
    """The fit against the rescued default it started from (`fit_from_default`).

    fit : the `NoiseFit`, started from ``default.result``'s noise. default : the rescued default
    (`ekfslam.analysis.rescue.Rescue`). kept : "fit" or "default". reason : why, in words.
    fit_log_likelihood, default_log_likelihood : ln L per sighting of each one's replay.
    gain : how much better the fit predicts the sightings the default accepted
    (`predictive_gain`).
    """

    fit: NoiseFit
    default: Rescue
    kept: str
    reason: str
    fit_log_likelihood: float
    default_log_likelihood: float
    gain: Gain

    @property
    def result(self) -> ReplayResult:
        """The replay kept."""
        return self.fit.result if self.kept == "fit" else self.default.result

    @property
    def noise(self) -> NoiseConfig:
        return self.result.noise

    def line(self) -> str:
        """One line: which noise was kept and why."""
        if self.kept == "fit":
            return f"noise: the fitted noise kept ({self.reason})"
        return f"noise: the default kept, not the fit ({self.reason})"

    def as_dict(self) -> dict:
        return {
            **self.fit.as_dict(),
            "kept": self.kept,
            "reason": self.reason,
            "fit_replay_log_likelihood": self.fit_log_likelihood,
            "default_replay_log_likelihood": self.default_log_likelihood,
            "gain_on_default_accepted": self.gain.as_dict(),
            "default_verdict": self.default.result.diagnosis.verdict,
            "default_rescue": self.default.as_dict(),
        }


def fit_from_default(
    run: RunLog,
    start: NoiseConfig | None = None,
    config: FilterConfig | None = None,
    *,
    max_evaluations: int = 200,
) -> FitChoice:
    """The rescued default (`replay_rescued` of `start`, `config`), the fit started from its
    noise and config (`fit_noise`), and the one kept (see the module): the fit only when its
    diagnosis is no worse and it predicts the sightings the default accepted better by more
    than `GAIN_Z` standard errors (`predictive_gain`)."""
    start = start or default_noise(run)
    config = config or default_config(run)
    default = replay_rescued(run, start, config)
    fit = fit_noise(
        run, default.result.noise, default.result.config, max_evaluations=max_evaluations
    )
    fit_ll, default_ll = log_likelihood(fit.result), log_likelihood(default.result)
    gain = predictive_gain(default.result, fit.result)
    fit_v, default_v = fit.diagnosis.verdict, default.result.diagnosis.verdict
    verdicts = f"the fit's replay is {fit_v}, the default's {default_v}"
    figures = (
        f"{gain.text()} on the sightings the default accepted; ln L per sighting "
        f"{fit_ll:.3f} against the default's {default_ll:.3f}"
    )
    if VERDICTS.index(fit_v) > VERDICTS.index(default_v):
        kept, reason = "default", verdicts
    elif not gain.significant:
        kept, reason = "default", f"the fit predicts no better: {figures}"
    else:
        kept, reason = "fit", f"it predicts better: {figures}; diagnosis {fit_v}"
    return FitChoice(fit, default, kept, reason, fit_ll, default_ll, gain)


def innovation_correlation(history: History, gap: float = CORRELATION_GAP) -> tuple[float, float]:
    """(ρ range, ρ bearing): the correlation of each innovation, normalised by its σ in S, with
    the next accepted sighting's of the same landmark at most `gap` s later (NaN: under 10
    pairs)."""
    accepted = np.flatnonzero(np.asarray(history.obs_outcome) == Outcome.ACCEPTED)
    ids = np.asarray(history.obs_id)[accepted]
    order = accepted[np.lexsort((accepted, ids))]  # by landmark, then in time
    first, second = order[:-1], order[1:]
    obs_t = np.asarray(history.obs_t)
    pairs = (np.asarray(history.obs_id)[first] == np.asarray(history.obs_id)[second]) & (
        obs_t[second] - obs_t[first] <= gap
    )
    first, second = first[pairs], second[pairs]
    if len(first) < 10:
        return math.nan, math.nan
    nu, S = np.asarray(history.obs_innovation), np.asarray(history.obs_S)
    rho = []
    for c in (0, 1):
        e = nu[:, c] / np.sqrt(S[:, c, c])
        a, b = e[first] - e[first].mean(), e[second] - e[second].mean()
        spread = math.sqrt(float(a @ a) * float(b @ b))
        rho.append(float(a @ b) / spread if spread > 0 else math.nan)
    return rho[0], rho[1]


def widened(noise: NoiseConfig, correlation: tuple[float, float]) -> NoiseConfig:
    """`noise` with σr and σφ times √((1 + ρ) / (1 - ρ)) for their correlation ρ > 0 (ρ at most
    `MAX_CORRELATION`; NaN or ρ <= 0 leaves σ as it is): an AR(1) error's long-run σ."""

    def factor(rho: float) -> float:
        if not math.isfinite(rho) or rho <= 0:
            return 1.0
        rho = min(rho, MAX_CORRELATION)
        return math.sqrt((1 + rho) / (1 - rho))

    rho_r, rho_b = correlation
    return dataclasses.replace(
        noise,
        sigma_range=noise.sigma_range * factor(rho_r),
        sigma_bearing=noise.sigma_bearing * factor(rho_b),
    )


_TESTED = (Outcome.ACCEPTED, Outcome.REJECTED, Outcome.REINITIALISED)


class _Cost:
    """-ln L per detection of the run at ln σ = x (`fit_noise`'s objective), memoised."""

    def __init__(
        self,
        run: RunLog,
        start: NoiseConfig,
        config: FilterConfig,
        fields: tuple[str, ...],
    ) -> None:
        self.run, self.start, self.config, self.fields = run, start, config, fields
        self.calls = 0
        self.per_sighting: dict[tuple, Array | None] = {}

    def noise(self, x: Array) -> NoiseConfig:
        sigmas = np.exp(np.clip(x, *np.log(BOUNDS))).tolist()
        return dataclasses.replace(self.start, **dict(zip(self.fields, sigmas, strict=True)))

    def terms(self, x: Array) -> Array | None:
        key = tuple(np.round(x, 12))
        if key not in self.per_sighting:
            self.calls += 1
            try:
                result = replay(self.run, self.noise(x), self.config)
            except EkfSlamError:  # the state overflowed: as bad as can be
                self.per_sighting[key] = None
                return None
            lost = None if result.diagnosis is None else result.diagnosis.lost_after
            self.per_sighting[key] = sighting_log_likelihoods(
                result.history, self.config.gate, lost
            )
        return self.per_sighting[key]

    def __call__(self, x: Array) -> float:
        x = np.asarray(x, dtype=float)
        if np.any(x < math.log(BOUNDS[0]) - 1e-9) or np.any(x > math.log(BOUNDS[1]) + 1e-9):
            return math.inf
        terms = self.terms(x)
        if terms is None or len(terms) == 0:
            return math.inf
        return float(-terms.sum() / len(terms))


def _standard_errors(cost: _Cost, x: Array) -> dict[str, float]:
    """{field: standard error of ln σ} from the outer product of the per-sighting scores."""
    nan = dict.fromkeys(cost.fields, math.nan)
    grads = []
    for k in range(len(x)):
        step = np.zeros(len(x))
        step[k] = SCORE_STEP
        up, down = cost.terms(x + step), cost.terms(x - step)
        if up is None or down is None:
            return nan
        grads.append((up - down) / (2 * SCORE_STEP))
    g = np.array(grads)  # (p, M)
    try:
        cov = np.linalg.inv(g @ g.T)
    except np.linalg.LinAlgError:
        return nan
    variances = np.diag(cov)
    se = np.sqrt(np.where(variances > 0, variances, np.nan))
    return dict(zip(cost.fields, se.tolist(), strict=True))
