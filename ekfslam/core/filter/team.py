"""One EKF over several robots: their poses and the landmarks they map, in one state.

The state is every robot's pose block (x, y, θ), in the order the robots entered, then the
landmarks (x, y), in the order they were first seen::

    μ = (p_1, p_2, ..., p_R, m_1, m_2, ..., m_n),    Σ = Cov(μ), (3R + 2n) x (3R + 2n)

A robot's rows are a parameter of every step, not rows 0:3: a prediction moves one robot's
block (eqs. 6, 7, 9) and leaves the others where they are; a landmark sighting corrects
through the one sensor model (eqs. 13-16, H non-zero on that robot's block and that landmark's);
a sighting of one robot by another through `ekfslam.core.models.ROBOT_RANGE_BEARING`, whose H is
non-zero on both robots' blocks, so it moves both poses (and, through Σ, the map).

Cost: a robot's prediction through a batch of increments runs on its 3x3 block alone, and its
correlations with the rest of the state are brought up to date once, when a correction needs
them (Σ[r, :] ← G Σ[r, :] with G the batch's product of eq. 7's Jacobians): O(n) per batch, as
the single filter's. A correction is O(n²) (eq. 16). Σ is kept whole, both halves current.

Each increment of a batch is the single filter's own step, `ekfslam.core.filter.steps.advance`
(eqs. 6, 7, 9 on the pose block, its G's product carried along), run as the straight-line code
`ekfslam.core.filter.generate` writes from its lines and the models' (the compiled filter's
stand-in for it), interpreted on Python floats: 2-3 µs an odometry row where the same lines on
numpy's 3x3 arrays cost 17-20 µs, most of a MRCLAM team's replay (its five robots drive 400,000-
630,000 odometry rows). Writing it costs sympy about a second, once per process and models; a
motion model it cannot write (`generate.NotStraightLine`) runs `advance` as written.

Robots may enter late (`add_robot`): a robot whose start is unknown is placed when it can be
(`ekfslam.team`), with its covariance, uncorrelated with the rest.

This is plain numpy (no numba): with a team the state is small (MRCLAM: 15 + 30 rows) and the
events many, so the cost is in Python's per-step overhead, not in the O(n²).
"""

from __future__ import annotations

import functools
import importlib
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.filter import steps
from ekfslam.core.filter.backend import steps_for
from ekfslam.core.filter.config import CHI2_2DOF_99
from ekfslam.core.filter.history import Outcome
from ekfslam.core.filter.predictions import Predicted, Rate, nearest_of, predictions_of
from ekfslam.core.filter.rebinding import interpreted, rebind
from ekfslam.core.models import (
    MIN_RANGE_SQUARED,
    ODOMETRY,
    RANGE_BEARING,
    ROBOT_RANGE_BEARING,
    MotionModel,
    RelativeModel,
    SensorModel,
)
from ekfslam.geometry import wrap_angle

Array = NDArray[np.float64]

#: The module that writes a step as straight-line code; it loads sympy (about 0.7 s), so it is
#: imported when a team first predicts, not with this module.
GENERATOR = "ekfslam.core.filter.generate"
#: `steps.advance`'s flags as the team runs it: noise per second of driving, the standard EKF.
ADVANCE_FLAGS = {"per_second": [True], "lin": [int(steps.Linearization.STANDARD)]}


@dataclass
class _Pending:
    """A robot's prediction not yet applied to its correlations: the batch's product of G's."""

    G: Array = field(default_factory=lambda: np.eye(3))
    steps: int = 0


class TeamEKF:
    """The joint filter of a team (module docstring): predict one robot, correct with a landmark
    sighting or with a sighting of another robot.

    Parameters
    ----------
    gate : the NIS threshold of every correction (χ²(2) 99% by default); None accepts all.
    motion, sensor, relative : the models (`ekfslam.core.models`): odometry, range-bearing to a
        landmark, range-bearing to another robot's centre.
    capacity : rows to allocate at first (the storage doubles when full).
    """

    def __init__(
        self,
        gate: float | None = CHI2_2DOF_99,
        motion: MotionModel = ODOMETRY,
        sensor: SensorModel = RANGE_BEARING,
        relative: RelativeModel = ROBOT_RANGE_BEARING,
        capacity: int = 64,
    ) -> None:
        self.gate = math.inf if gate is None else float(gate)
        self.motion, self.sensor, self.relative = motion, sensor, relative
        self._mu = np.zeros(capacity)
        self._Sigma = np.zeros((capacity, capacity))
        self.d = 0  # rows in use
        self.rows: dict[int, int] = {}  # robot -> its first row
        self.slot: dict[int, int] = {}  # landmark id -> its first row
        self._pending: dict[int, _Pending] = {}
        self._headings = np.zeros(0, dtype=np.int64)  # every robot's θ row
        #: the NIS of the last sighting the gate tested (NaN: it was not tested), for the
        #: diagnosis (`ekfslam.core.diagnosis`), as the single filter's history records it
        self.last_nis = math.nan

    # ------------------------------------------------------------------------- the state
    @property
    def mu(self) -> Array:
        """The mean (d,), a copy."""
        self._settle()
        return self._mu[: self.d].copy()

    @property
    def Sigma(self) -> Array:
        """The covariance (d, d), both halves current, a copy."""
        self._settle()
        return self._Sigma[: self.d, : self.d].copy()

    def pose(self, robot: int) -> Array:
        """Robot `robot`'s pose (x, y, θ), a copy."""
        r = self.rows[robot]
        return self._mu[r : r + 3].copy()

    def pose_covariance(self, robot: int) -> Array:
        """Robot `robot`'s 3x3 pose covariance (current: its block is kept at every step)."""
        r = self.rows[robot]
        return self._Sigma[r : r + 3, r : r + 3].copy()

    def landmark_map(self) -> dict[int, Array]:
        """{landmark id: (x, y)} of every landmark in the state."""
        return {i: self._mu[l : l + 2].copy() for i, l in self.slot.items()}

    def landmark_covariances(self) -> dict[int, Array]:
        """{landmark id: its 2x2 covariance}."""
        self._settle()
        return {i: self._Sigma[l : l + 2, l : l + 2].copy() for i, l in self.slot.items()}

    # -------------------------------------------------------------------------- growing
    def add_robot(
        self,
        robot: int,
        pose: ArrayLike,
        covariance: ArrayLike | None = None,
        depends: Mapping[int, ArrayLike] | None = None,
    ) -> None:
        """Put robot `robot` into the state at `pose`, with `covariance` (3x3, zero by default).

        depends : {placed robot: A (3x3)}: the new pose's first-order dependence on those robots'
            poses (δpose = Σ_p A_p δp_p + an independent error of covariance `covariance`), as a
            new landmark depends on its observer (eq. 12): Σ[new, :] = Σ_p A_p Σ[p, :] and
            Σ[new, new] = Σ_p Σ_q A_p Σ[p, q] A_qᵀ + covariance. None: no correlation with what
            is already there.
        """
        if robot in self.rows:
            raise ValueError(f"robot {robot} is already in the team's state")
        pose = np.asarray(pose, dtype=float)
        P = np.zeros((3, 3)) if covariance is None else np.asarray(covariance, dtype=float)
        if pose.shape != (3,) or P.shape != (3, 3) or not np.all(np.isfinite(pose)):
            raise ValueError(f"robot {robot}: pose must be (3,) finite, covariance (3, 3)")
        links = {p: np.asarray(A, dtype=float) for p, A in (depends or {}).items()}
        for p, A in links.items():
            if p not in self.rows or A.shape != (3, 3):
                raise ValueError(f"robot {robot}: depends on robot {p}, not placed or A not 3x3")
        self._settle()
        r = self._grow(3)
        S = self._Sigma
        self._mu[r : r + 3] = pose
        self._mu[r + 2] = wrap_angle(float(pose[2]))
        S[r : r + 3, :] = 0.0
        S[:, r : r + 3] = 0.0
        cross = np.zeros((3, r))
        for p, A in links.items():
            cross += A @ S[self.rows[p] : self.rows[p] + 3, :r]
        block = P.copy()
        for p, A in links.items():
            block += cross[:, self.rows[p] : self.rows[p] + 3] @ A.T
        S[r : r + 3, :r] = cross
        S[:r, r : r + 3] = cross.T
        S[r : r + 3, r : r + 3] = 0.5 * (block + block.T)
        self.rows[robot] = r
        self._headings = np.append(self._headings, r + 2)

    def _grow(self, k: int) -> int:
        """Room for k more rows; returns the first."""
        if self.d + k > len(self._mu):
            n = max(2 * len(self._mu), self.d + k)
            mu, Sigma = np.zeros(n), np.zeros((n, n))
            mu[: self.d] = self._mu[: self.d]
            Sigma[: self.d, : self.d] = self._Sigma[: self.d, : self.d]
            self._mu, self._Sigma = mu, Sigma
        first = self.d
        self.d += k
        return first

    # ------------------------------------------------------------------------- prediction
    def predict_many(self, robot: int, us: ArrayLike, dts: ArrayLike, M: ArrayLike) -> None:
        """Move robot `robot` through the increments us (K, 3), of durations dts (K,) s, with the
        control noise M (3x3) per second: eqs. (6), (7) and (9) on its pose block, R = V (M dt)
        Vᵀ (`steps.advance`, as the single filter's ``predict_many``). Its correlations with the
        rest of the state follow when a correction needs them."""
        r = self.rows[robot]
        us, dts = np.asarray(us, dtype=float), np.asarray(dts, dtype=float)
        M = np.asarray(M, dtype=float)
        if us.ndim != 2 or us.shape[1] != 3 or dts.shape != us.shape[:1] or M.shape != (3, 3):
            raise ValueError("predict_many: us must be (K, 3), dts (K,) and M (3, 3)")
        pending = self._pending.setdefault(robot, _Pending())
        block = np.zeros(steps.BLOCK)  # `steps.advance`'s: pose, P, the batch's G product, ...
        block[steps.POSE : steps.COV] = self._mu[r : r + 3]
        block[steps.COV : steps.PRODUCT] = self._Sigma[r : r + 3, r : r + 3].ravel()
        block[steps.PRODUCT : steps.BEFORE] = pending.G.ravel()
        block[steps.BEFORE : steps.OWED] = self._mu[r : r + 3]
        lin = int(steps.Linearization.STANDARD)
        advance, on_floats = _advance(self.motion, self.sensor)
        if on_floats:  # Python floats, a list, N read as N[i, j]: no numpy scalar per number
            cells = block.tolist()
            N = {(i, j): float(M[i, j]) for i in range(3) for j in range(3)}
            for u, dt in zip(us.tolist(), dts.tolist(), strict=True):
                advance(cells, u, N, dt, True, lin)
            block[:] = cells
        else:
            for u, dt in zip(us, dts, strict=True):
                advance(block, u, M, float(dt), True, lin)
        self._mu[r : r + 3] = block[steps.POSE : steps.COV]
        P = block[steps.COV : steps.PRODUCT].reshape(3, 3)
        # both halves the same bits (G P Gᵀ in floating point is not)
        self._Sigma[r : r + 3, r : r + 3] = 0.5 * (P + P.T)
        pending.G = block[steps.PRODUCT : steps.BEFORE].reshape(3, 3).copy()
        pending.steps += len(us)

    def widen(self, robot: int, R: ArrayLike) -> None:
        """Add R (3x3) to robot `robot`'s pose covariance: a prediction with no motion (eq. 9
        with G = I), which leaves every correlation as it is, so Σ stays positive semi-definite
        (`ekfslam.core.recovery`'s widening of a lost robot)."""
        r = self.rows[robot]
        R = np.asarray(R, dtype=float)
        self._Sigma[r : r + 3, r : r + 3] += 0.5 * (R + R.T)

    def landmark(self, landmark_id: int) -> tuple[Array, Array]:
        """(mean (2,), covariance (2, 2)) of landmark `landmark_id`."""
        self._settle()
        l = self.slot[landmark_id]
        return self._mu[l : l + 2].copy(), self._Sigma[l : l + 2, l : l + 2].copy()

    def _settle(self) -> None:
        """Bring every robot's correlations up to date with its pending predictions:
        Σ[r, o] ← G Σ[r, o] for the other rows o (and its transpose), one robot after another,
        so two robots' cross block becomes G_a Σ_ab G_bᵀ."""
        d, S = self.d, self._Sigma
        for robot, pending in self._pending.items():
            if not pending.steps:
                continue
            r = self.rows[robot]
            block = S[r : r + 3, r : r + 3].copy()  # already predicted, noise and all
            S[r : r + 3, :d] = pending.G @ S[r : r + 3, :d]
            S[:d, r : r + 3] = S[r : r + 3, :d].T
            S[r : r + 3, r : r + 3] = block
        self._pending.clear()

    # ------------------------------------------------------------------------- correction
    def update(self, robot: int, z: ArrayLike, landmark_id: int, Q: ArrayLike) -> Outcome:
        """Robot `robot` sees landmark `landmark_id` at z = (r, φ) with noise Q (2x2): a new
        landmark enters the map (eq. 12, with its cross-covariance), a known one corrects the
        state (eqs. 13-16), if its NIS passes the gate."""
        z, Q = np.asarray(z, dtype=float), np.asarray(Q, dtype=float)
        r = self.rows[robot]
        self._settle()
        self.last_nis = math.nan
        if landmark_id not in self.slot:
            return self._place(r, z, Q, landmark_id)
        l = self.slot[landmark_id]
        pose, m = self._mu[r : r + 3], self._mu[l : l + 2]
        if not _apart(pose, m):
            return Outcome.REFUSED
        z_hat = self.sensor.h(pose, m)  # eq. (13)
        H_r, H_l = self.sensor.H(pose, m)  # eq. (14)'s two blocks
        return self._correct((r, H_r), (l, H_l), self.sensor.innovation(z, z_hat), Q)

    def update_robot(self, observer: int, target: int, z: ArrayLike, Q: ArrayLike) -> Outcome:
        """Robot `observer` sees robot `target`'s centre at z = (r, φ) with noise Q: both poses
        are corrected (H non-zero on both blocks), if the NIS passes the gate."""
        z, Q = np.asarray(z, dtype=float), np.asarray(Q, dtype=float)
        a, b = self.rows[observer], self.rows[target]
        self._settle()
        self.last_nis = math.nan
        pa, pb = self._mu[a : a + 3], self._mu[b : b + 3]
        if not _apart(pa, pb):
            return Outcome.REFUSED
        z_hat = self.relative.h(pa, pb)
        H_a, H_b = self.relative.H(pa, pb)
        return self._correct((a, H_a), (b, H_b), self.relative.innovation(z, z_hat), Q)

    def nis(self, robot: int, z: ArrayLike, landmark_id: int, Q: ArrayLike) -> float:
        """The NIS a landmark sighting would have (no change to the state)."""
        r, l = self.rows[robot], self.slot[landmark_id]
        self._settle()
        pose, m = self._mu[r : r + 3], self._mu[l : l + 2]
        nu = self.sensor.innovation(np.asarray(z, float), self.sensor.h(pose, m))
        H_r, H_l = self.sensor.H(pose, m)
        _, S = self._innovation_covariance((r, H_r), (l, H_l), np.asarray(Q, float))
        return float(nu @ np.linalg.solve(S, nu))

    def _innovation_covariance(self, *blocks) -> tuple[Array, Array]:
        """H Σ (2, d) from the blocks (first row, H's block) and S = H Σ Hᵀ + Q, eq. (15)."""
        *blocks, Q = blocks
        d, S = self.d, self._Sigma
        HSigma = sum(H @ S[i : i + H.shape[1], :d] for i, H in blocks)
        innovation = Q.copy()
        for i, H in blocks:
            innovation += HSigma[:, i : i + H.shape[1]] @ H.T
        return HSigma, innovation

    def _correct(self, first, second, nu: Array, Q: Array) -> Outcome:
        """Eqs. (15)-(16) with H non-zero on two blocks: K = Σ Hᵀ S⁻¹, μ += K ν, Σ -= K S Kᵀ."""
        HSigma, S = self._innovation_covariance(first, second, Q)
        if not np.all(np.isfinite(S)):
            return Outcome.SINGULAR
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        if not (det > 0.0 and S[0, 0] > 0.0):
            return Outcome.SINGULAR
        S_inv = np.array(((S[1, 1], -S[0, 1]), (-S[1, 0], S[0, 0]))) / det
        self.last_nis = float(nu @ S_inv @ nu)
        if self.last_nis > self.gate:
            return Outcome.REJECTED
        d = self.d
        K = HSigma.T @ S_inv  # (d, 2)
        self._mu[:d] += K @ nu  # eq. (16)
        # every robot's heading, in one call: the same wrap, the same bits, as one at a time
        self._mu[self._headings] = wrap_angle(self._mu[self._headings])
        self._Sigma[:d, :d] -= K @ HSigma  # Σ - K H Σ
        self._Sigma[:d, :d] = 0.5 * (self._Sigma[:d, :d] + self._Sigma[:d, :d].T)
        return Outcome.ACCEPTED

    def _place(self, r: int, z: Array, Q: Array, landmark_id: int) -> Outcome:
        """A new landmark at g(pose, z), eq. (12): Σ[l, :] = G_r Σ[r, :], Σ[l, l] = G_r Σ_rr G_rᵀ
        + G_z Q G_zᵀ, O(n)."""
        pose = self._mu[r : r + 3].copy()
        m = self.sensor.g(pose, z)
        G_r, G_z = self.sensor.G(pose, z)
        l = self._grow(2)
        d, S = self.d, self._Sigma
        self._mu[l : l + 2] = m
        S[l : l + 2, :d] = 0.0
        S[:d, l : l + 2] = 0.0
        cross = G_r @ S[r : r + 3, :l]
        S[l : l + 2, :l] = cross
        S[:l, l : l + 2] = cross.T
        block = G_r @ S[r : r + 3, r : r + 3] @ G_r.T + G_z @ Q @ G_z.T
        S[l : l + 2, l : l + 2] = 0.5 * (block + block.T)
        self.slot[landmark_id] = l
        return Outcome.INITIALISED


class RobotView:
    """One robot's part of a `TeamEKF` (its pose and the map) under the single filter's names
    (`ekfslam.core.filter.ekf.EKFSLAM`'s ``mu``, ``Sigma``, ``nearest``, ``predictions``,
    ``update`` ...), so that `ekfslam.core.filter.associating.AssociatingFilter` decides the
    robot's sightings with hidden ids against the joint map exactly as it decides a single
    robot's: the predictions of every landmark (eqs. 13-15) depend on that robot's pose and the
    landmarks only, so they are the single filter's step functions run on that sub-state.

    update : (landmark id, z, Q, t) -> Outcome, how the team's replay corrects the joint
        filter with a paired sighting (with its recovery and its counts).
    backend : the step functions' ("python" or "numba", `ekfslam.core.filter.backend`).
    """

    def __init__(
        self, joint: TeamEKF, robot: int, update: Callable, backend: str = "python"
    ) -> None:
        self.joint, self.robot, self._update = joint, robot, update
        self.sensor = joint.sensor
        self.steps = steps_for(joint.motion, joint.sensor, backend)

    @property
    def landmark_ids(self) -> list[int]:
        """The joint map's landmark ids, in slot (row) order."""
        return list(self.joint.slot)

    @property
    def n_landmarks(self) -> int:
        return len(self.joint.slot)

    def _rows(self) -> NDArray[np.int64]:
        r = self.joint.rows[self.robot]
        rows = [r, r + 1, r + 2]
        for l in self.joint.slot.values():
            rows += [l, l + 1]
        return np.array(rows, dtype=np.int64)

    @property
    def mu(self) -> Array:
        """(3 + 2n,) the robot's pose, then the landmarks (a copy)."""
        return self.joint.mu[self._rows()]

    @property
    def Sigma(self) -> Array:
        """Their covariance (3 + 2n, 3 + 2n), a copy."""
        rows = self._rows()
        return self.joint.Sigma[np.ix_(rows, rows)]

    @property
    def pose_covariance(self) -> Array:
        return self.joint.pose_covariance(self.robot)

    def _arrays(self) -> tuple[tuple, int]:
        mu, Sigma = self.mu, np.ascontiguousarray(self.Sigma)
        lin = int(steps.Linearization.STANDARD)
        return tuple(steps.Storage(mu, Sigma, mu.copy(), np.zeros(2), lin)), len(mu)

    def predictions(self, zs: Array, Q: Array, rate: Rate | None = None) -> Predicted:
        """`EKFSLAM.predictions` on the robot's sub-state (`predictions_of`)."""
        arrays, d = self._arrays()
        return predictions_of(self.steps, arrays, d, zs, Q, rate)

    def nearest(self, zs: Array, Q: Array, gate: float) -> tuple[list[int], list[float]]:
        """`EKFSLAM.nearest` on the robot's sub-state (`nearest_of`)."""
        arrays, d = self._arrays()
        return nearest_of(self.steps, arrays, d, zs, Q, gate)

    def update(self, landmark_id: int, z, Q, t: float | None = None, validate: bool = True):
        """A paired sighting: the replay's correction of the joint filter (``update``)."""
        return self._update(int(landmark_id), z, Q, t)


@functools.cache
def _advance(motion: MotionModel, sensor: SensorModel) -> tuple[Callable, bool]:
    """`steps.advance` for these models: the straight-line code `generate` writes from its
    lines, to run on Python floats (True), or, for a model it cannot write, `advance` as
    written, on numpy arrays (False)."""
    models = {"motion": motion, "sensor": sensor}
    as_written = rebind({"advance": steps.advance}, models, interpreted).advance
    generator = importlib.import_module(GENERATOR)
    spec = {**steps.STRAIGHT_LINE["advance"], **ADVANCE_FLAGS}
    try:
        source = generator.straight_line(steps.advance, spec, models, "advance")
    except generator.NotStraightLine:
        return as_written, False
    scope = {"math": math, "wrap_angle": wrap_angle}
    exec(compile(source, f"<{GENERATOR}: advance>", "exec"), scope)
    return scope["advance"], True


def _apart(a: Array, b: Array) -> bool:
    return (b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 > MIN_RANGE_SQUARED
