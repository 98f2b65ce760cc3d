"""The filter's steps in block form: what runs, compiled or not, is what is written here.

One prediction batch (eqs. 6, 7, 9), one correction (eqs. 13-16) and one new landmark (eq. 12),
on the blocks of μ and Σ they touch, after Solà's EKF-SLAM toolbox: ``r`` = the robot's rows
0:3, ``L`` = one landmark's rows l : l+2, ``m`` = the map's rows 3:d. The seed writes the same
steps with the lifts F_x (eq. 8) and F_x,j (eq. 14); `ekfslam.teaching.reference` is that
literal form, the oracle these steps are tested against.

The models are called by name, ``motion.f``, ``sensor.h``, ... (`ekfslam.core.models`); this
module binds those names to the seed's robot and camera. `ekfslam.core.filter.backend` makes
the steps for other models, and compiles them with numba (`ekfslam.core.filter.compile`): the
same lines, ``@`` and all, become machine code. They are written for both: numpy on small
arrays, no Python objects beyond the `NamedTuple`s below.

Storage (`Storage`): μ and Σ live in pre-allocated arrays larger than the state; the state is
their first d = 3 + 2n entries. The records below (`Storage`, `Batch`, `Update`, `Observed`)
name the fields of the tuples the steps take; the filter passes plain tuples, which numba
dispatches on in a microsecond where a named tuple costs three, and each step unpacks them at its
top. Σ is kept whole and exactly symmetric (`ekfslam.core.filter.symmetric`): every step that
writes a block writes its transpose too, so any read of Σ is current.

Three linearisations (`Linearization`): the standard EKF; FEJ (Huang, Mourikis & Roumeliotis
2010: the Jacobians at the first estimates); and the right-invariant EKF (Barrau & Bonnabel
2015, `ekfslam.core.invariant`), whose Σ is the covariance of the invariant error ξ: its motion
Jacobian is the identity, its noise A R Aᵀ reaches the map (the O(n²) part is owed, `settle`),
its H is eq. (14)'s times the error map T(μ̂), and it corrects through the group's exponential.
"""

from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from ekfslam.core.filter.history import (
    OBS_EVENT,
    OBS_ID,
    OBS_LANDMARK,
    OBS_LANDMARK_COV,
    OBS_NIS,
    OBS_OUTCOME,
    OBS_T,
    OBS_Z,
    OBSERVE,
    PREDICT,
    ROW,
    ROW_COV,
    ROW_POSE,
    ROW_T,
    Outcome,
    obs_width,
)
from ekfslam.core.filter.symmetric import (
    diagonal_block,
    rows_of,
    set_block,
    set_rows,
    subtract_products,
)
from ekfslam.core.invariant import (
    INVARIANT_NEW_LANDMARK_POSE,
    landmark_to_cartesian,
    retract,
    rotation_column,
    to_cartesian,
)
from ekfslam.core.models import MIN_RANGE_SQUARED, ODOMETRY, RANGE_BEARING
from ekfslam.geometry import wrap_angle

Array = NDArray[np.float64]

#: The models the steps call (see the module): the seed's, unless the backend binds others.
motion = ODOMETRY
sensor = RANGE_BEARING


class Linearization(IntEnum):
    """Where the Jacobians are evaluated (`ekfslam.core.filter.config.FilterConfig`)."""

    STANDARD = 0
    FEJ = 1
    INVARIANT = 2


class Storage(NamedTuple):
    """The filter's arrays, which the steps change in place (`ekfslam.core.filter.state`).

    mu : (capacity,) the mean of eq. (1) in its first d entries, zero beyond.
    Sigma : (capacity, capacity) its covariance, eq. (2), both triangles current (symmetric).
    first : (capacity,) FEJ's first estimates: the pose predicted for this step p̂(k|k-1) at
        0:3, landmark j's first estimate at 3+2j : 5+2j.
    owed : (2,) the invariant filter's heading variance ρ not yet added to the map block, and
        the rows it is owed to (the landmarks mapped when it arose); see `settle`.
    linearization : a `Linearization`: what Σ is the covariance of, and where H is evaluated.
    """

    mu: Array
    Sigma: Array
    first: Array
    owed: Array
    linearization: int


class Batch(NamedTuple):
    """K control increments to predict through (`predict`).

    u : (K, k) controls, k the motion model's `control_size` (the seed's body-frame increments
    (Δux, Δuy, Δθ), eq. (4)); dt : (K,) s; t : (K,) s, the time after each. N : the noise: the
    control covariance per second M (k, k) when per_second (step k gets R_k = V (M dt_k) Vᵀ),
    else a fixed state-space R (3, 3) for every step (the seed's way).
    """

    u: Array
    dt: Array
    t: Array
    N: Array
    per_second: bool


class Update(NamedTuple):
    """One observation as the correction uses it (`correct`).

    z : (m,) the measurement, eq. (10) (m: the sensor's `SensorModel.size`); Q : (m, m) its
    noise, eq. (11); gate : the largest NIS
    accepted (inf: no gate); point : (5,) the pose and the landmark at which H is evaluated
    (the estimate; FEJ's first estimates; the iterated update's last point).
    """

    z: Array
    Q: Array
    gate: float
    point: Array


class Sighting(NamedTuple):
    """One sighting of a mapped landmark as `sight` takes it: its time (s), the landmark's id,
    z (2,), Q (2, 2), the gate (the largest NIS accepted; inf: none) and the index of its event
    row (-1: no history is kept, nothing is recorded)."""

    t: float
    landmark_id: int
    z: Array
    Q: Array
    gate: float
    event: int


class Plan(NamedTuple):
    """D detections of a run as `feed` takes them, and what it needs to decide alone.

    upto : (D,) the prediction pieces that end by each detection; landmark_id, z (D, 2), Q
    (D, 2, 2), t (D,): each detection; code (D,) its id's index in slot_of (U,), the slot of
    each distinct id (-1: not mapped yet). gate: the largest NIS accepted (inf: none), applied
    once a landmark has gate_after accepted sightings (sightings (n,), per slot); pending (n,):
    the slots whose last sightings were rejected; stop_on_reject: does a rejection go back to
    the filter (which may place the landmark again, `FilterConfig.reinit_after`). clock (1,):
    the time of the last event fed.
    """

    upto: NDArray[np.int64]
    landmark_id: NDArray[np.int64]
    z: Array
    Q: Array
    t: Array
    code: NDArray[np.int64]
    slot_of: NDArray[np.int64]
    gate: float
    gate_after: int
    sightings: NDArray[np.int64]
    pending: NDArray[np.bool_]
    stop_on_reject: bool
    clock: Array


class Tape(NamedTuple):
    """The history's arrays (`Recorder`'s) that `feed` writes its events into, with room for
    every event it may feed; no rows: nothing recorded."""

    rows: Array
    kinds: NDArray[np.int8]
    obs: Array


#: `feed`'s cursor (an int array, read and advanced): the next detection, the pieces predicted,
#: the history's event rows and observation rows used, the predictions made, and from
#: `AT_OUTCOMES` on how many sightings had each `Outcome`
AT_DETECTION, AT_PIECE, AT_ROW, AT_OBS, AT_PREDICTIONS, AT_OUTCOMES = 0, 1, 2, 3, 4, 5


class Observed(NamedTuple):
    """One observation as the history records it (`record_observation`): its time (s), the
    landmark's id, z (2,), the `Outcome` and the index of its event row."""

    t: float
    landmark_id: int
    z: Array
    outcome: int
    event: int


# ----------------------------------------------------------------------------- prediction
#: `advance`'s block: where the pose block's state through a batch lies in one small array
POSE, COV, PRODUCT, BEFORE, OWED, BLOCK = 0, 3, 12, 21, 24, 27


def predict(storage: Storage, d: int, batch: Batch, rows: Array) -> None:
    """Predict through a batch of increments, eqs. (6), (7) and (9), on the blocks they touch.

    The landmarks do not move, so of Σ only the pose block Σ[r, r] changes at every step
    (`advance`), and the pose-map block Σ[r, m] changes once for the whole batch, by the product
    of its G's: O(n) for the batch. rows : (K, `ROW`) receives the pose and its covariance after
    each step, or has no rows (nothing recorded).
    """
    mu, Sigma, first, owed_now, lin = storage
    u_all, dt, t, N, per_second = batch
    r, m = slice(0, 3), slice(3, d)
    if lin == Linearization.INVARIANT and owed_now[0] != 0.0 and owed_now[1] != d:
        settle(storage, d)  # landmarks came in since: what is owed is owed to fewer rows
    block = np.zeros(BLOCK)  # the pose block's state through the batch, `advance`'s
    block[POSE:COV] = mu[r]
    block[COV:PRODUCT] = diagonal_block(Sigma, 0, 3).ravel()  # Σ[r, r]
    block[PRODUCT:BEFORE] = np.eye(3).ravel()
    block[BEFORE:OWED] = first[r]
    for k in range(u_all.shape[0]):
        advance(block, u_all[k], N, dt[k], per_second, lin)
        if rows.shape[0]:
            record_pose(rows[k], t[k], block[POSE:COV], block[COV:PRODUCT].reshape(3, 3), lin)
    mu[r], first[r] = block[POSE:COV], block[BEFORE:OWED]
    set_block(Sigma, 0, block[COV:PRODUCT].reshape(3, 3))
    if lin == Linearization.INVARIANT:  # the noise's map columns: its heading column times -J m̂
        Sigma[r, m] += np.outer(block[OWED:BLOCK], -rotation_column(mu[:d])[m])
        owed_now[0] += block[OWED + 2]  # the map block's ρ v vᵀ, O(n²): owed (`settle`)
        owed_now[1] = d
    else:  # eq. (9) on the pose-map block, G the product of the batch's G's
        Sigma[r, m] = block[PRODUCT:BEFORE].reshape(3, 3) @ Sigma[r, m]
    Sigma[m, r] = Sigma[r, m].T  # and its mirror, Σ[m, r] = Σ[r, m]ᵀ


def advance(block: Array, u: Array, N: Array, dt: float, per_second: bool, lin: int) -> None:
    """One increment u on the pose block, eqs. (6), (7) and (9), in place.

    block (`BLOCK`,): the pose (x, y, θ) at `POSE`; its covariance P (3x3, row by row) at
    `COV`; the product of the batch's G's so far at `PRODUCT`; FEJ's pose predicted at the last
    step, p̂(k|k-1), at `BEFORE`; the invariant filter's noise column owed to the map at
    `OWED`. N, dt, per_second: the control noise per second and the step's duration (R = V (N
    dt) Vᵀ), or a fixed R = N. One small array in, the same array out: compiled, this step runs
    as straight-line code generated from these lines (`ekfslam.core.filter.generate`).
    """
    pose, before, owed = block[POSE:COV], block[BEFORE:OWED], block[OWED:BLOCK]
    P, G_batch = block[COV:PRODUCT].reshape(3, 3), block[PRODUCT:BEFORE].reshape(3, 3)
    G = motion.F_x(pose, u, dt)  # eq. (7), at the pose before the step
    R = N
    if per_second:  # eq. (9)'s R: the control noise through V (3 x k), R = V M Vᵀ
        V = motion.F_v(pose, u, dt)
        R = V @ (N * dt) @ V.T
    pose[:] = motion.f(pose, u, dt)  # eq. (6)
    if lin == Linearization.INVARIANT:  # ξ's motion Jacobian is I; its noise A R Aᵀ
        G = np.eye(3)
        A = invariant_noise_map(pose)
        R = A @ R @ A.T
        owed += R[:, 2]
    elif lin == Linearization.FEJ:  # at the predicted positions, not the updated one
        G = fej_motion_jacobian(before, pose)
    P[:] = G @ P @ G.T + R  # eq. (9) on the pose block
    G_batch[:] = G @ G_batch
    before[:] = pose


#: The steps the compiled filter runs as straight-line code generated from their lines
#: (`ekfslam.core.filter.generate`), with the shapes of their arguments (a flag: its values, a
#: list; "control": the motion model's `MotionModel.control_size`; N's shape by per_second: the
#: control covariance per second, k x k, or the fixed state-space R, 3x3).
STRAIGHT_LINE = {
    "advance": {
        "block": (BLOCK,),
        "u": ("control",),
        "N": {"per_second": {True: ("control", "control"), False: (3, 3)}},
        "dt": (),
        "per_second": [False, True],
        "lin": [int(v) for v in Linearization],
    }
}


def fej_motion_jacobian(before: Array, after: Array) -> Array:
    """FEJ's G of eq. (7): I + J (p̂(k+1|k) - p̂(k|k-1)) e₃ᵀ, from the positions predicted at the
    step's two ends instead of the updated estimate's increment (Huang et al. 2010, eq. 31)."""
    return np.array(
        (
            (1.0, 0.0, before[1] - after[1]),
            (0.0, 1.0, after[0] - before[0]),
            (0.0, 0.0, 1.0),
        )
    )


def invariant_noise_map(pose: Array) -> Array:
    """The pose rows of A = T(μ̂)⁻¹ F_xᵀ (`ekfslam.core.invariant.noise_map`): I - (J p̂, 0) e₃ᵀ."""
    return np.array(((1.0, 0.0, pose[1]), (0.0, 1.0, -pose[0]), (0.0, 0.0, 1.0)))


def settle(storage: Storage, d: int) -> None:
    """Add the heading noise the invariant filter owes its map block, Σ[m, m] += ρ v vᵀ with
    v = -J m̂ on the owed rows (`predict`): O(n²), so the filter does it once, before Σ is read
    or the map grows, and a correction does it in its own pass."""
    _, Sigma, _, owed, _ = storage
    rho = owed[0]
    if rho != 0.0:  # ρ v vᵀ = u uᵀ, u = √ρ v: symmetric to the bit (`subtract_products`)
        u = np.sqrt(rho) * owed_direction(storage, d)
        subtract_products(Sigma, d, (-u).reshape(1, d), u.reshape(1, d))
        owed[0] = 0.0


def owed_direction(storage: Storage, d: int) -> Array:
    """v (d,): -J m̂ on the rows owed the heading noise (`Storage.owed`), 0 on the others."""
    mu, _, _, owed, _ = storage
    v = -rotation_column(mu[:d])
    v[:3] = 0.0
    v[int(owed[1]) :] = 0.0
    return v


# ------------------------------------------------------------------------------- correction
def correct(storage: Storage, d: int, l: int, update: Update, obs: Array) -> int:
    """Use one observation of the landmark at rows l, l+1, eqs. (13)-(16); returns an `Outcome`
    as its code (an int: compiled, an enum member would be rebuilt at every return).

    Only ACCEPTED changes μ and Σ. REJECTED: the NIS exceeds the gate. REFUSED: the landmark, or
    the point H is evaluated at, sits on the robot. SINGULAR: S is not positive definite, or not
    finite. obs (`obs_row`) receives ẑ, ν, S and the NIS, NaN where not reached. z has the
    sensor's m numbers (`SensorModel.size`), Q is m x m, S too: its Cholesky factor is a
    loop over m (`cholesky`), 2x2 for the seed's range and bearing, 1x1 for a bearing.
    """
    mu, Sigma, _, owed, lin = storage
    z, Q, gate, point = update
    r, L = slice(0, 3), slice(l, l + 2)
    obs[OBS_Z + z.shape[0] :] = np.nan  # ẑ, ν, S
    obs[OBS_NIS] = np.nan
    if not (apart(mu[r], mu[L]) and apart(point[:3], point[3:])):
        return Outcome.REFUSED.value
    z_hat = sensor.h(mu[r], mu[L])  # eq. (13)
    nu = sensor.innovation(z, z_hat)  # z - ẑ, the bearing wrapped
    H_r, H_l = jacobians(storage, point)  # eq. (14)'s two non-zero blocks
    HSigma = H_r @ rows_of(Sigma, 0, 3, d) + H_l @ rows_of(Sigma, l, 2, d)  # H Σ, O(n)
    rho = owed[0]
    if rho != 0.0:  # the invariant filter's Σ still owes ρ v vᵀ (`settle`)
        v = owed_direction(storage, d)
        HSigma += rho * np.outer(H_l @ v[L], v)
    S = HSigma[:, r] @ H_r.T + HSigma[:, L] @ H_l.T + Q  # eq. (15)'s H Σ Hᵀ + Q
    record_innovation(obs, z_hat, nu, S)
    C = cholesky(S)  # S = C Cᵀ
    if not positive(C):
        return Outcome.SINGULAR.value
    w = solve_lower(C, nu)  # the NIS νᵀ S⁻¹ ν is |w|²
    nis = w @ w
    obs[OBS_NIS] = nis
    if nis > gate:
        return Outcome.REJECTED.value
    W = solve_lower(C, HSigma)  # K = Σ Hᵀ S⁻¹ = Wᵀ C⁻¹, so K S Kᵀ = Wᵀ W
    step = W.T @ w  # K ν = (H Σ)ᵀ S⁻¹ ν, eq. (15)
    if lin == Linearization.INVARIANT:
        mu[:d] = retract(mu[:d], step)  # exp(K ν) μ̂: the group's exponential
    else:
        mu[:d] += step  # eq. (16)
        mu[2] = wrap_angle(mu[2])
    if rho != 0.0:  # Σ + ρ v vᵀ - Wᵀ W in one pass, ρ v vᵀ = u uᵀ with u = √ρ v
        u = (np.sqrt(rho) * v).reshape(1, d)
        subtract_products(Sigma, d, np.vstack((W, -u)), np.vstack((W, u)))
        owed[0] = 0.0
    else:
        subtract_products(Sigma, d, W, W)  # eq. (16): Σ - K S Kᵀ = (I - K H) Σ
    return Outcome.ACCEPTED.value


def record_innovation(obs: Array, z_hat: Array, nu: Array, S: Array) -> None:
    """ẑ, ν (m,) and S (m, m) into an observation row (`obs_row`), S's lower triangle written to
    both halves (the history's S exactly symmetric, as Σ is kept)."""
    m = z_hat.shape[0]
    obs[OBS_Z + m : OBS_Z + 2 * m] = z_hat
    obs[OBS_Z + 2 * m : OBS_Z + 3 * m] = nu
    at = OBS_Z + 3 * m
    for i in range(m):
        for j in range(m):
            obs[at + i * m + j] = S[i, j] if i >= j else S[j, i]


def sight(storage: Storage, d: int, l: int, sighting: Sighting, row: Array, obs: Array) -> int:
    """A sighting of the landmark at rows l, l+1: corrected (`correct`, H at
    `linearisation_point`) and recorded (`record_observation`; not when its event's index is
    -1, a filter that keeps no history), the filter's commonest step in one call. Returns the
    `Outcome`'s code."""
    t, landmark_id, z, Q, gate, event = sighting
    outcome = correct(storage, d, l, (z, Q, gate, linearisation_point(storage, l)), obs)
    if event >= 0:
        record_observation(storage, d, l, (t, landmark_id, z, outcome, event), row, obs)
    return outcome


def feed(storage: Storage, d: int, pieces: Batch, plan: Plan, tape: Tape, at: NDArray) -> None:
    """A run's detections from at[`AT_DETECTION`] on, each after its prediction pieces
    (`predict`, one batch per detection), sighted (`sight`) and counted, and the pieces after
    the last one: a replay's loop, as many `predict` and `sight` calls as the filter's own
    steps make. It stops before a detection that needs the filter to decide (a landmark not
    mapped yet, or one whose sightings were rejected), and before it counts a rejection when
    `Plan.stop_on_reject`; `at` (`AT_DETECTION` ...) says where it stopped.
    """
    u, dt, t, N, per_second = pieces
    upto, landmark_id, z, Q, seen_at, code, slot_of, gate, gate_after = plan[:9]
    sightings, pending, stop_on_reject, clock = plan[9:]
    rows, kinds, obs = tape
    recording = rows.shape[0] > 0
    spare_row, spare_obs = np.empty(len(ROW)), np.empty(obs_width(z.shape[1]))  # nothing kept
    i, done, n, m = at[AT_DETECTION], at[AT_PIECE], at[AT_ROW], at[AT_OBS]
    while i <= upto.shape[0]:
        p = upto[i] if i < upto.shape[0] else u.shape[0]  # after the last detection: the end
        if p > done:
            k = p - done
            batch = (u[done:p], dt[done:p], t[done:p], N, per_second)
            predict(storage, d, batch, rows[n : n + k] if recording else rows[:0])
            if recording:
                kinds[n : n + k] = PREDICT
                n += k
            at[AT_PREDICTIONS] += k
            clock[0] = t[p - 1]
            done = p
        j = slot_of[code[i]] if i < upto.shape[0] else -1
        if j < 0 or pending[j]:
            break
        row, ob = (rows[n], obs[m]) if recording else (spare_row, spare_obs)
        gated = gate if sightings[j] >= gate_after else np.inf
        sighting = (seen_at[i], landmark_id[i], z[i], Q[i], gated, n)  # a `Sighting`
        outcome = sight(storage, d, 3 + 2 * j, sighting, row, ob)
        if outcome == Outcome.REJECTED.value and stop_on_reject:
            break
        if recording:
            kinds[n] = OBSERVE
            n, m = n + 1, m + 1
        if outcome == Outcome.ACCEPTED.value:
            sightings[j] += 1
        at[AT_OUTCOMES + outcome] += 1
        clock[0] = seen_at[i]
        i += 1
    at[AT_DETECTION], at[AT_PIECE], at[AT_ROW], at[AT_OBS] = i, done, n, m


def linearisation_point(storage: Storage, l: int) -> Array:
    """Where H is evaluated (5,): the pose and the landmark at rows l, l+1 as estimated, or
    FEJ's first estimates (the pose predicted for this step, the landmark when first placed)."""
    mu, _, first, _, lin = storage
    at = first if lin == Linearization.FEJ else mu
    return np.array((at[0], at[1], at[2], at[l], at[l + 1]))


def jacobians(storage: Storage, point: Array) -> tuple[Array, Array]:
    """H's two blocks (eq. 14) at point (5,) = (pose, landmark), in the filter's error: the
    Cartesian one, or the invariant ξ's, H T with δp = ξ_p + J p ξ_θ and δm = ξ_m + J m ξ_θ."""
    lin = storage[4]  # the storage's linearization
    H_r, H_l = sensor.H(point[:3], point[3:])
    if lin == Linearization.INVARIANT:
        H_r[:, 2] += H_r[:, :2] @ quarter_turn(point[:2]) + H_l @ quarter_turn(point[3:])
    return H_r, H_l


def quarter_turn(p: Array) -> Array:
    """J p = (-p_y, p_x): a point's motion under a unit rotation about the origin."""
    return np.array((-p[1], p[0]))


def apart(pose: Array, landmark: Array) -> bool:
    """Is the landmark off the robot, so that its bearing is defined (`MIN_RANGE_SQUARED`)?"""
    dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
    return dx * dx + dy * dy > MIN_RANGE_SQUARED


def cholesky(S: Array) -> Array:
    """The lower-triangular C with C Cᵀ = S (k x k); NaN where S is not positive definite.

    numpy's (LAPACK's) here; compiled, a loop over S's lower triangle (`ekfslam.core.filter.
    compile`), since for a 2x2 the call into LAPACK costs more than its arithmetic."""
    try:
        return np.linalg.cholesky(S)
    except np.linalg.LinAlgError:
        return np.full(S.shape, np.nan)


def positive(C: Array) -> bool:
    """Did `cholesky` succeed, with a determinant a float holds: every pivot finite and positive,
    and det S = Π C_ii² neither 0 nor inf (noise so small, or so large, that S means nothing)?
    Compiled, a loop over C (`ekfslam.core.filter.compile`)."""
    pivots = np.diag(C)
    det = np.prod(pivots) ** 2
    return bool(np.isfinite(C).all() and (pivots > 0.0).all() and 0.0 < det < np.inf)


def solve_lower(C: Array, b: Array) -> Array:
    """x with C x = b, C lower triangular, by forward substitution (b: (k,) or (k, d))."""
    x = b.copy()
    for i in range(C.shape[0]):
        for j in range(i):
            x[i] -= C[i, j] * x[j]
        x[i] /= C[i, i]
    return x


def solve_upper(C: Array, b: Array) -> Array:
    """x with Cᵀ x = b, C lower triangular, by back substitution (b: (k,))."""
    x = b.copy()
    for i in range(C.shape[0] - 1, -1, -1):
        for j in range(i + 1, C.shape[0]):
            x[i] -= C[j, i] * x[j]
        x[i] /= C[i, i]
    return x


# ------------------------------------------------------------------------------ landmarks
def place_landmark(storage: Storage, d: int, l: int, update: Update, seed_variance: float) -> None:
    """Put a landmark into rows l, l+1 (d counts them) from one sighting, eq. (12), dropping
    whatever they held.

    Its covariance through eq. (12)'s Jacobians, Σ[L, :d] = G_r Σ[r, :d] (its correlation with
    the robot and every mapped landmark) and Σ[L, L] = G_r Σ[r, r] G_rᵀ + G_z Q G_zᵀ; or, with
    seed_variance > 0, eq. (3)'s "infinite" covariance as seed_variance I, uncorrelated (the
    seed's way, followed by an update with the same sighting). For an invertible sensor
    (`SensorModel.g`); one that needs two sightings is placed by `set_landmark`.
    """
    mu, Sigma, first, _, lin = storage
    z, Q, _, _ = update
    r, L = slice(0, 3), slice(l, l + 2)
    pose = mu[r].copy()
    mu[L] = sensor.g(pose, z)  # eq. (12)
    first[L] = mu[L]  # FEJ: its first estimate
    if seed_variance > 0.0:  # eq. (3): nothing known, no correlation
        rows = np.zeros((2, d))
        rows[:, L] = seed_variance * np.eye(2)
    else:
        G_r, G_z = sensor.G(pose, z)
        if lin == Linearization.INVARIANT:  # ξ_m = ξ_p + G_z δz
            G_r = INVARIANT_NEW_LANDMARK_POSE.copy()
        rows = G_r @ rows_of(Sigma, 0, 3, d)  # Σ[L, :d] = G_r Σ[r, :d]
        own = G_r @ rows[:, r].T + G_z @ Q @ G_z.T  # Σ[L, L]
        rows[:, L] = 0.5 * (own + own.T)
    set_rows(Sigma, l, d, rows)


def set_landmark(storage: Storage, d: int, l: int, landmark: Array, rows: Array) -> None:
    """Put a landmark at `landmark` (2,) into rows l, l+1 (d counts them) with its rows of Σ,
    rows (2, d) = Σ[L, :d], its own block included: where two sightings placed it, with its
    cross-covariance (`ekfslam.core.filter.delayed.Clones.place`)."""
    mu, Sigma, first, _, _ = storage
    mu[l : l + 2] = landmark
    first[l : l + 2] = landmark  # FEJ: its first estimate
    set_rows(Sigma, l, d, rows)


# -------------------------------------------------------------------------------- history
def record_pose(row: Array, t: float, pose: Array, P: Array, lin: int) -> None:
    """One event row (`ROW`): the time, the pose and its covariance (Cartesian, always)."""
    if lin == Linearization.INVARIANT:
        P = to_cartesian(P, pose)
    row[ROW_T] = t
    row[ROW_POSE : ROW_POSE + 3] = pose
    c = ROW_COV  # its six distinct entries: xx, xy, xθ, yy, yθ, θθ
    row[c], row[c + 1], row[c + 2] = P[0, 0], P[1, 0], P[2, 0]
    row[c + 3], row[c + 4], row[c + 5] = P[1, 1], P[2, 1], P[2, 2]


def record_observation(
    storage: Storage, d: int, l: int, observed: Observed, row: Array, obs: Array
) -> None:
    """The state after an observation into its event row (`ROW`) and the observation into its
    row (`obs_row`, whose ẑ, ν, S and NIS `correct` wrote). l < 0: the landmark has no slot
    (a refused first sighting), so its estimate is NaN. Covariances are Cartesian."""
    mu, Sigma, _, owed, lin = storage
    t, landmark_id, z, outcome, event = observed
    record_pose(row, t, mu[:3], diagonal_block(Sigma, 0, 3), lin)
    obs[OBS_T], obs[OBS_EVENT], obs[OBS_ID] = t, event, landmark_id
    obs[OBS_Z : OBS_Z + z.shape[0]] = z
    obs[OBS_OUTCOME] = outcome
    if l < 0:
        obs[OBS_LANDMARK : OBS_LANDMARK_COV + 4] = np.nan
        return
    M = diagonal_block(Sigma, l, 2)  # the landmark's own block Σ[L, L]
    if lin == Linearization.INVARIANT:  # δm = ξ_m + J m̂ ξ_θ, and the heading noise owed
        v = owed_direction(storage, d)[l : l + 2]
        M = landmark_to_cartesian(
            M + owed[0] * np.outer(v, v), Sigma[2, l : l + 2], Sigma[2, 2], mu[l : l + 2]
        )
    obs[OBS_LANDMARK : OBS_LANDMARK + 2] = mu[l : l + 2]
    obs[OBS_LANDMARK_COV : OBS_LANDMARK_COV + 4] = M.ravel()
