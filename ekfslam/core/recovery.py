"""Recovery: a filter that rejects every sighting for a stretch does not stay lost in silence.

When the pose estimate has drifted beyond what its covariance admits, every sighting of a mapped
landmark fails the NIS gate (a χ² test on S = H Σ Hᵀ + Q, eq. 15), so nothing corrects the pose,
and Σ grows only by the motion noise that was too small in the first place: the filter is lost
for good. On MRCLAM robots whose odometry is held for a second at a time, the tuned default
rejects 60-90% of the sightings from some moment on and ends 1-3 m off.

`Recovery` watches the outcomes. After `RecoveryConfig.after` consecutive rejected sightings of at
least `RecoveryConfig.landmarks` different landmarks (one landmark rejected many times is a
biased range, as MRCLAM robot 4's stretches of tags 11-13 read 0.3-0.5 m short, not a lost pose),
it widens the pose covariance by what those innovations say the pose error is: σθ² from their
bearing innovations (a heading error δθ moves every bearing by -δθ) and σ² in x and y from their
range innovations (a position error moves a landmark's range along its ray), each their mean
square. The next sightings then pass the gate and pull the pose back onto the map: a
relocalisation against the landmarks it still holds. The map is not touched (re-initialising
landmarks would throw away what the robot saw before it was lost) and, with the ids known, there
is nothing to re-associate.

The widening is a prediction with no motion whose noise is that covariance, through the filter's
public API (`predict(0, R)`: eq. 9 with G = I adds R to the pose block and leaves every
correlation as it is, so Σ stays positive semi-definite). It shows in the history as one more
prediction at the time of the sighting that triggered it, and `Recovery.times` lists them for the
diagnosis (`ekfslam.core.diagnosis`).

`Recovery` stands between a replay's loop and the filter (`ekfslam.pipeline.replay`'s
``recovery``): it has the filter's ``predict_many`` and ``update`` and hands everything else to
it. Plain numpy: it never loads the filter itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ekfslam.core.filter.history import Outcome
from ekfslam.core.models import observation
from ekfslam.errors import ConfigError
from ekfslam.geometry import wrap_angle


@dataclass(frozen=True)
class RecoveryConfig:
    """When to widen the pose covariance of a filter that rejects everything.

    after : consecutive rejected sightings (accepted ones reset the count; new landmarks neither
        count nor reset it).
    landmarks : of at least this many different landmarks.
    """

    after: int = 20
    landmarks: int = 2

    def __post_init__(self) -> None:
        for name in ("after", "landmarks"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(
                    f"RecoveryConfig.{name} must be a whole number >= 1, got {value!r}"
                )
        if self.landmarks > self.after:
            raise ConfigError("RecoveryConfig.landmarks cannot exceed after")


class Recovery:
    """A filter's steps, with its pose covariance widened after a run of rejections (see the
    module).

    filter : the filter (`ekfslam.core.filter.ekf.EKFSLAM`, or anything with ``predict``,
    ``predict_many``, ``update``, ``pose`` and ``landmark``). config : when.
    """

    def __init__(self, filter: Any, config: RecoveryConfig | None = None) -> None:
        self.filter = filter
        self.config = config or RecoveryConfig()
        self.times: list[float] = []  # when the covariance was widened, s
        self._innovations: list[tuple[float, float]] = []
        self._seen: set[int] = set()

    def predict_many(self, *args: Any, **kwargs: Any) -> None:
        self.filter.predict_many(*args, **kwargs)

    def update(
        self, landmark_id: int, z: ArrayLike, Q: ArrayLike, t: float | None = None, **options: Any
    ) -> Outcome:
        """The filter's update (with `options`); after it, a rejection may complete a run that
        triggers a widening."""
        outcome = self.filter.update(landmark_id, z, Q, t, **options)
        if outcome == Outcome.ACCEPTED:
            self._innovations.clear()
            self._seen.clear()
        elif outcome == Outcome.REJECTED:
            mean, _ = self.filter.landmark(landmark_id)
            z_hat = observation(self.filter.pose, mean)
            nu_r = float(z[0]) - float(z_hat[0])
            nu_b = wrap_angle(float(z[1]) - float(z_hat[1]))
            self._innovations.append((nu_r, nu_b))
            self._seen.add(int(landmark_id))
            c = self.config
            if len(self._innovations) >= c.after and len(self._seen) >= c.landmarks:
                self._widen(t)
        return outcome

    def feed(self, *args: Any, **kwargs: Any) -> None:
        """Not the filter's `feed`, which would pass the run by unwatched: step it through
        `predict_many` and `update` (as `ekfslam.pipeline.replay` does)."""
        raise TypeError("Recovery watches each update: feed it with predict_many and update")

    def _widen(self, t: float | None) -> None:
        nu = np.array(self._innovations)
        position, heading = np.mean(nu**2, axis=0).tolist()
        R = np.diag([position, position, heading])
        self.filter.predict(np.zeros(3), R, t)
        self.times.append(math.nan if t is None else float(t))
        self._innovations.clear()
        self._seen.clear()

    def __getattr__(self, name: str) -> Any:  # mu, Sigma, counts, history(): the filter's
        return getattr(self.filter, name)
