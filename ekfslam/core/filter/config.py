"""What can be chosen about the EKF-SLAM filter, and what it counts.

`FilterConfig` holds the choices that change the algorithm (landmark initialisation, gating,
re-initialisation, linearisation); the noise levels R and Q are passed with each step instead.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

from ekfslam.errors import ConfigError
from ekfslam.fieldtypes import field_types

if TYPE_CHECKING:
    from ekfslam.core.filter.history import Outcome
    from ekfslam.core.models import MotionModel, SensorModel


def chi2_2dof_quantile(p: float) -> float:
    """The chi-square quantile for 2 degrees of freedom at probability p (0 <= p < 1).

    With 2 dof the distribution is exponential, P(x) = 1 - exp(-x/2), so its quantile is
    -2 ln(1 - p) (log1p keeps the digits for p near 1): 5.99 at 95%, 9.21 at 99%.
    """
    return -2.0 * math.log1p(-p)


#: The filter's linearisations (`FilterConfig.linearization`), in the order tables list them.
LINEARIZATIONS = ("standard", "fej", "invariant")

#: chi-square(2 dof) 99% quantile (9.2103...): the default Mahalanobis gate on (r, φ) innovations.
CHI2_2DOF_99 = chi2_2dof_quantile(0.99)


#: The most passes `ekfslam.pipeline.replay` makes with hidden ids (each reads the run again).
MAX_PASSES = 10

#: `FilterConfig.backend`'s choices: "python" runs the steps as written, "numba" compiled,
#: "auto" decides per use (a replay by the run's size, `backend_for`; a filter built directly by
#: the events its models have run, `ekfslam.core.filter.backend.auto_steps`).
BACKENDS = ("auto", "python", "numba")

#: With "auto", a run of more events than this (predictions and sightings) runs compiled:
#: below it, loading the compiled steps (about 0.3 s) costs more than it saves.
COMPILE_ABOVE_EVENTS = 20_000


@dataclass(frozen=True)
class FilterConfig:
    """Choices that change how the filter behaves (noise levels are passed per step).

    init : "inverse" (default) initialises a new landmark through the inverse observation
        eq. (12) with its full cross-covariance; "seed" reproduces the report: eq. (12) for the
        mean, eq. (3)'s "infinite" covariance as `seed_init_variance`, then the update eq. (15)-(16)
        with the same observation.
    seed_init_variance : m^2. The finite stand-in for eq. (3)'s ∞.
    gate : Mahalanobis threshold on the NIS νᵀS⁻¹ν (default chi²(2) 99% = 9.21); None disables.
    gate_after : the gate applies to a landmark once it has this many accepted sightings
        (its initialisation counts as one). With 1, the sighting after the initialisation is
        already gated: the inverse-observation covariance is what it is checked against.
    reinit_after, reinit_radius : a landmark whose last `reinit_after` sightings (or, if more,
        as many as it has accepted) were all rejected by the gate, and put it within
        `reinit_radius` m of each other but not within that of another landmark (that would be
        a misread id of the other one), was itself initialised from a bad sighting: it is
        initialised again from the latest sighting, its old estimate and correlations dropped.
        None disables. The "as many as it has accepted" keeps a well-confirmed landmark in place
        when its sightings are rejected because the pose has drifted: re-placing it then would
        discard the loop closure (on the 15-landmark loop, 8 in 200 clean runs did, and FEJ's
        pose NEES left its band on 18% of steps instead of 7%).
    initial_capacity : landmarks to pre-allocate for (the storage doubles when full).
    linearization : "standard" evaluates every Jacobian at the latest estimate; "fej" is the
        First-Estimates Jacobian EKF (Huang, Mourikis & Roumeliotis, IJRR 2010): the motion
        Jacobian of eq. (7) uses the predicted positions p̂(k+1|k) - p̂(k|k-1) and the observation
        Jacobian of eq. (14) the robot's predicted position and each landmark's first estimate,
        so the filter does not gain spurious information about the global heading;
        "invariant" is the right-invariant EKF on SE_{1+n}(2) (Barrau & Bonnabel, "An EKF-SLAM
        algorithm with consistency properties", 2015): the filter keeps the covariance of the
        invariant error ξ (`ekfslam.core.invariant`), whose Jacobians do not depend on the
        estimate along the unobservable directions (a global shift and rotation), and corrects
        through the group's exponential. The mean is the same (x, y, θ, landmarks) and the
        covariance is reported Cartesian (`EKFSLAM.Sigma`, the history), to first order.
    iterations : linearisations of each update (1, the default: the plain EKF of eqs. 13-16).
        N > 1 is the iterated EKF, Gauss-Newton on the filter's error coordinates (Bell &
        Cathey 1993): H of eq. (14) is evaluated again at the updated estimate, up to N times,
        while each step lowers the observation's MAP cost, until a step moves by less than
        1e-7 (`ekfslam.core.filter.iterated`). The gate and the recorded NIS stay the first
        linearisation's. Not with "fej", whose point is to keep each Jacobian where it was
        first evaluated.
    motion, sensor : the models the filter uses (`ekfslam.core.models`): None (the default)
        is the seed's robot (`ODOMETRY`) and camera (`RANGE_BEARING`). Another sensor is a
        `SensorModel` of any measurement size, another robot a `MotionModel` of any control
        size; nothing else changes. The gate's default is χ²(2)'s: a sensor of another size m
        takes χ²(m)'s (99%: 6.63 for m = 1, 11.34 for m = 3). A sensor that needs two
        sightings to place a landmark (a bearing alone, `SensorModel.triangulate`) takes
        init "inverse" and reinit_after None (both place a landmark from one sighting).
    min_parallax, max_spread : for a sensor that needs two sightings: a held first sighting
        and a later one place the landmark once their rays meet at min_parallax rad or more
        (0.05, 2.9°, by default) and the landmark's largest standard deviation is at most
        max_spread of its distance (0.1: a wider one is far from Gaussian along its ray;
        `ekfslam.core.initialisation`).
    backend : "python" runs the filter's steps (`ekfslam.core.filter.steps`) as written;
        "numba" runs them compiled from that source (`ekfslam.core.filter.compile`: the first
        run on a machine compiles, about a minute, and caches); "auto" (the default) decides
        per use: a filter built directly (a user's own loop) starts on the Python steps and
        takes the compiled ones once its models have run
        `ekfslam.core.filter.backend.COMPILE_AFTER_EVENTS` events in the process (a cold
        cache is compiled in another process meanwhile), and `ekfslam.pipeline.replay`
        chooses "numba" for a run of more than `COMPILE_ABOVE_EVENTS` events, and
        `ekfslam.pipeline.batch_config` for a batch of replays that together have more (a
        Monte Carlo, a noise fit).
        Both give the same numbers to rounding.
    """

    init: Literal["inverse", "seed"] = "inverse"
    linearization: Literal["standard", "fej", "invariant"] = "standard"
    seed_init_variance: float = 1e6
    gate: float | None = CHI2_2DOF_99
    gate_after: int = 1
    reinit_after: int | None = 3
    reinit_radius: float = 0.1
    initial_capacity: int = 16
    iterations: int = 1
    motion: MotionModel | None = None
    sensor: SensorModel | None = None
    backend: Literal["auto", "python", "numba"] = "auto"
    min_parallax: float = 0.05
    max_spread: float = 0.1

    def __post_init__(self) -> None:
        field_types(self)
        if self.linearization not in LINEARIZATIONS:
            raise ConfigError(
                f"linearization must be 'standard', 'fej' or 'invariant', "
                f"got {self.linearization!r}"
            )
        if self.init not in ("inverse", "seed"):
            raise ConfigError(f"init must be 'inverse' or 'seed', got {self.init!r}")
        if not self.seed_init_variance > 0:
            raise ConfigError("seed_init_variance must be positive")
        if self.gate is not None and not self.gate > 0:
            raise ConfigError("gate must be positive or None")
        if self.gate_after < 1:
            raise ConfigError("gate_after must be at least 1")
        if self.reinit_after is not None and self.reinit_after < 2:
            raise ConfigError("reinit_after must be at least 2 (or None)")
        if not self.reinit_radius > 0:
            raise ConfigError("reinit_radius must be positive")
        if self.initial_capacity < 1:
            raise ConfigError("initial_capacity must be at least 1")
        if isinstance(self.iterations, bool) or not (
            isinstance(self.iterations, int) and 1 <= self.iterations <= 100
        ):
            raise ConfigError(
                f"iterations must be a whole number 1 to 100, got {self.iterations!r}"
            )
        if self.backend not in BACKENDS:
            raise ConfigError(f"backend must be one of {', '.join(BACKENDS)}, got {self.backend!r}")
        for name, fields in (("motion", ("f", "F_x", "F_v")), ("sensor", ("h", "H"))):
            model = getattr(self, name)
            if model is not None and not all(callable(getattr(model, f, None)) for f in fields):
                raise ConfigError(
                    f"{name} must be a {name.capitalize()}Model of ekfslam.core.models (with "
                    f"{', '.join(fields)}), got {type(model).__name__}"
                )
        if self.motion is not None:
            _takes_control_and_dt(self.motion)
        if not 0.0 < self.min_parallax < math.pi:
            raise ConfigError(f"min_parallax must be in (0, π) rad, got {self.min_parallax!r}")
        if not self.max_spread > 0.0:
            raise ConfigError(f"max_spread must be positive, got {self.max_spread!r}")
        if self.sensor is not None and getattr(self.sensor, "g", None) is None:
            name = getattr(self.sensor, "name", "?")
            if self.init != "inverse" or self.reinit_after is not None:
                raise ConfigError(
                    f"sensor {name!r} places a landmark from two sightings (triangulate): it "
                    "needs init='inverse' and reinit_after=None, which place one from one"
                )
            if self.linearization != "standard" or self.iterations != 1:
                raise ConfigError(
                    f"sensor {name!r} places a landmark from two sightings: its held poses' "
                    "clones follow the standard EKF with one linearisation (linearization="
                    "'standard', iterations=1)"
                )
        if self.iterations > 1 and self.linearization == "fej":
            raise ConfigError(
                "iterations > 1 needs linearization 'standard' or 'invariant': FEJ keeps each "
                "Jacobian at its first estimate, which iterating would move"
            )


def _takes_control_and_dt(motion: MotionModel) -> None:
    """A motion model's f, F_x and F_v each take (pose, u, dt), or one `ConfigError` says which
    does not (a model written for f(pose, u) before the control and dt reached every function)."""
    for field in ("f", "F_x", "F_v"):
        fn = getattr(motion, field)
        try:
            inspect.signature(fn).bind(None, None, None)
        except TypeError:
            raise ConfigError(
                f"motion {getattr(motion, 'name', '?')!r}: {field} must take (pose, u, dt), the "
                f"control and the step's duration in s (ekfslam.core.models.MotionModel)"
            ) from None
        except ValueError:  # a builtin without a signature: called as it is
            continue


@dataclass(frozen=True)
class FilterCounts:
    """How many steps of each kind the filter took; nothing is dropped without being counted.

    One field per `ekfslam.core.filter.history.Outcome`, named by its `label`, besides the
    predictions: the outcome fields add up to the observations the filter was given.
    """

    predictions: int
    initialised: int
    accepted: int
    rejected: int
    refused: int
    reinitialised: int = 0
    singular: int = 0  # S singular or not finite (see `ekfslam.core.filter.history.Outcome`)
    deferred: int = 0  # a first sighting held for a second (a bearing-only sensor)

    def of(self, outcome: Outcome) -> int:
        """How many observations had this outcome."""
        return getattr(self, outcome.label)


def backend_for(config: FilterConfig, events: int) -> FilterConfig:
    """`config` with "auto" resolved for a run of `events` predictions and sightings."""
    if config.backend != "auto":
        return config
    return dataclasses.replace(
        config, backend="numba" if events > COMPILE_ABOVE_EVENTS else "python"
    )
