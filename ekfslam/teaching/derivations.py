"""The seed's models derived symbolically with sympy, their Jacobians, and the seed's slips.

Every model of `ekfslam.core.models` is rebuilt here from its equation and differentiated by sympy,
so a notebook can show each Jacobian and the tests can check the hand-written numeric forms:

- motion, eq. (6): f(pose, u) with G = ∂f/∂pose (the 3x3 block of eq. 7) and V = ∂f/∂u;
- observation, eq. (13) with atan2: ẑ(pose, m) with H_pose (2x3) and H_landmark (2x2), eq. (14);
- inverse observation, eq. (12): m(pose, z) with ∂m/∂pose (2x3) and ∂m/∂z (2x2).

It also shows, with sympy itself, where the seed's printed equations go wrong or right: eq. (14)
as printed is right; arctan(δy/δx) in eq. (13) is off by π when δx < 0; and the lifts F_x (·) F_xᵀ
of eqs. (7) and (9) are not defined for a 3x3 inner matrix once the map holds a landmark.

Derivations are cached with functools.cache (sympy is slow) and nothing is derived at import time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ekfslam.core.models import MIN_RANGE_SQUARED, DegenerateGeometry
from ekfslam.geometry import wrap_angle

Array = NDArray[np.float64]

from ekfslam.teaching.symbols import (  # noqa: E402 (the notebooks' names, kept apart)
    CONTROL,
    LANDMARK,
    MEASUREMENT,
    POSE,
    TARGET,
    delta_x,
    delta_y,
    dtheta,
    du_x,
    du_y,
    m_x,
    m_y,
    phi,
    q,
    r,
    sigma_phi,
    sigma_r,
    theta,
    theta_b,
    x,
    x_b,
    y,
    y_b,
)

#: Control-increment covariance M (u-space), a general 3x3 matrix of symbols.
M_SYMBOLS = sp.ImmutableMatrix(3, 3, sp.symbols("M_0:3(0:3)", real=True))

_LATEX_NAMES = {
    du_x: r"\Delta u_x",
    du_y: r"\Delta u_y",
    dtheta: r"\Delta \theta",
    m_x: r"\mu_{j,x}",
    m_y: r"\mu_{j,y}",
    x_b: "x_b",
    y_b: "y_b",
    theta_b: r"\theta_b",
    delta_x: r"\delta_x",
    delta_y: r"\delta_y",
    sigma_r: r"\sigma_r",
    sigma_phi: r"\sigma_\phi",
}


@dataclass(frozen=True)
class SymbolicModel:
    """One model of the seed in sympy form with its two Jacobians.

    `value` is a column matrix in the symbols `POSE` and `inputs`; `jacobian_pose` is
    ∂value/∂POSE and `jacobian_input` is ∂value/∂inputs. `labels` are the LaTeX names of the three
    (for example ``("f", "G", "V")``).
    """

    name: str
    equation: str
    inputs: tuple[sp.Symbol, ...]
    value: sp.ImmutableMatrix
    jacobian_pose: sp.ImmutableMatrix
    jacobian_input: sp.ImmutableMatrix
    labels: tuple[str, str, str]

    def latex(self) -> tuple[str, str, str]:
        """LaTeX of ``label = expression`` for the value and the two Jacobians."""
        exprs = (self.value, self.jacobian_pose, self.jacobian_input)
        return tuple(latex(e, lhs) for lhs, e in zip(self.labels, exprs, strict=True))


def latex(expr: sp.Basic, lhs: str | None = None) -> str:
    """LaTeX of a sympy expression in the seed's notation (Δu_x, μ_{j,x}, δ_x, ...).

    With `lhs` the result reads ``lhs = ...``, ready for ``IPython.display.Math``.
    """
    body = sp.latex(expr, symbol_names=_LATEX_NAMES)
    return body if lhs is None else f"{lhs} = {body}"


def _model(
    name: str,
    equation: str,
    inputs: tuple[sp.Symbol, ...],
    value: list[sp.Expr],
    labels: tuple[str, str, str],
) -> SymbolicModel:
    value = sp.ImmutableMatrix(value)
    return SymbolicModel(
        name=name,
        equation=equation,
        inputs=inputs,
        value=value,
        jacobian_pose=sp.ImmutableMatrix(value.jacobian(POSE)),
        jacobian_input=sp.ImmutableMatrix(value.jacobian(inputs)),
        labels=labels,
    )


@cache
def motion_model() -> SymbolicModel:
    """Eq. (6): the pose after the body-frame increment u; G = ∂f/∂pose, V = ∂f/∂u."""
    c, s = sp.cos(theta), sp.sin(theta)
    f = [x + du_x * c - du_y * s, y + du_x * s + du_y * c, theta + dtheta]
    return _model("motion", "(6)", CONTROL, f, ("f", "G", "V"))


@cache
def observation_model() -> SymbolicModel:
    """Eq. (13) with atan2: ẑ = (√q, atan2(δy, δx) - θ); H_pose = ∂ẑ/∂pose, H_landmark = ∂ẑ/∂m."""
    dx, dy = m_x - x, m_y - y
    z_hat = [sp.sqrt(dx**2 + dy**2), sp.atan2(dy, dx) - theta]
    return _model("observation", "(13)", LANDMARK, z_hat, (r"\hat{z}", "H_{pose}", "H_{landmark}"))


@cache
def robot_observation_model() -> SymbolicModel:
    """Another robot seen by this one: ẑ = (√q, atan2(δy, δx) - θ) with δ = (x_b, y_b) - (x, y);
    H_a = ∂ẑ/∂pose (this robot), H_b = ∂ẑ/∂(x_b, y_b, θ_b) (the robot it sees)."""
    dx, dy = x_b - x, y_b - y
    z_hat = [sp.sqrt(dx**2 + dy**2), sp.atan2(dy, dx) - theta]
    return _model("robot_observation", "(13)", TARGET, z_hat, (r"\hat{z}", "H_a", "H_b"))


@cache
def inverse_observation_model() -> SymbolicModel:
    """Eq. (12): the landmark seen at z = (r, φ) from the pose; Jacobians w.r.t. pose and z."""
    m = [x + r * sp.cos(phi + theta), y + r * sp.sin(phi + theta)]
    return _model("inverse_observation", "(12)", MEASUREMENT, m, ("m", "G_{pose}", "G_{z}"))


@cache
def motion_noise_expr() -> sp.ImmutableMatrix:
    """R = V M Vᵀ (3x3): the control covariance M (`M_SYMBOLS`) mapped into the state."""
    V = motion_model().jacobian_input
    return sp.ImmutableMatrix(V * M_SYMBOLS * V.T)


def observation_noise_expr() -> sp.ImmutableMatrix:
    """Q, eq. (11): diag(σ_r², σ_φ²)."""
    return sp.ImmutableMatrix(sp.diag(sigma_r**2, sigma_phi**2))


# --- eq. (14): the seed's printed H against the derived one ------------------------------------


@cache
def derived_observation_jacobian() -> sp.ImmutableMatrix:
    """[H_pose | H_landmark] (2x5) derived from eq. (13), written in δx = μx - x, δy = μy - y."""
    model = observation_model()
    block = model.jacobian_pose.row_join(model.jacobian_input)
    return sp.ImmutableMatrix(sp.simplify(block.subs({m_x: x + delta_x, m_y: y + delta_y})))


def seed_observation_jacobian() -> sp.ImmutableMatrix:
    """Eq. (14) as printed, without F_x,j (2x5), in the symbols δx, δy and q (= δx² + δy²).

    (1/q) [[-√q δx, -√q δy, 0, √q δx, √q δy], [δy, -δx, -q, -δy, δx]], transcribed literally.
    """
    return sp.ImmutableMatrix(_seed_observation_factors()[1]) / q


def _seed_observation_factors() -> tuple[sp.Expr, sp.ImmutableMatrix]:
    sq = sp.sqrt(q)
    inner = [
        [-sq * delta_x, -sq * delta_y, 0, sq * delta_x, sq * delta_y],
        [delta_y, -delta_x, -q, -delta_y, delta_x],
    ]
    return 1 / q, sp.ImmutableMatrix(inner)


def seed_observation_jacobian_latex() -> str:
    """LaTeX of eq. (14) in the seed's own layout, the factor 1/q kept outside the matrix."""
    factor, inner = _seed_observation_factors()
    return f"H = {latex(factor)} {latex(inner)}"


def observation_jacobian_difference(candidate: sp.ImmutableMatrix) -> sp.ImmutableMatrix:
    """Derived [H_pose | H_landmark] minus a candidate 2x5 matrix in δx, δy (and q), simplified.

    q is replaced by δx² + δy² before the comparison; an all-zero result means they agree.
    """
    candidate = sp.ImmutableMatrix(candidate).subs(q, delta_x**2 + delta_y**2)
    return sp.ImmutableMatrix(sp.simplify(derived_observation_jacobian() - candidate))


@cache
def seed_observation_jacobian_difference() -> sp.ImmutableMatrix:
    """Derived minus printed eq. (14), term by term, simplified (2x5): all zeros as they agree."""
    return observation_jacobian_difference(seed_observation_jacobian())


# --- eq. (13): arctan(δy/δx) against atan2 -----------------------------------------------------


def seed_bearing_expr() -> sp.Expr:
    """The seed's bearing of eq. (13), arctan(δy/δx) - θ, as sympy (for display)."""
    return sp.atan(delta_y / delta_x) - theta


@dataclass(frozen=True)
class BearingComparison:
    """The seed's arctan bearing against atan2 for one offset δ = (dx, dy) in m; angles in rad."""

    dx: float
    dy: float
    seed_arctan: float  # arctan(dy/dx) - θ, wrapped
    atan2: float  # atan2(dy, dx) - θ, wrapped
    difference: float  # atan2 - seed_arctan, wrapped: 0 when dx > 0, -π when dx < 0


def compare_bearings(dx: float, dy: float, theta_rad: float = 0.0) -> BearingComparison:
    """Both bearings of eq. (13) for the offset (dx, dy) seen from heading `theta_rad`.

    arctan only sees the ratio dy/dx, so it cannot tell (dx, dy) from (-dx, -dy): whenever dx < 0
    its answer points the opposite way, off by π. At dx = 0 the seed's ratio is ±∞ and arctan's
    limit ±π/2 is used.
    """
    if dx == 0.0 and dy == 0.0:
        raise DegenerateGeometry("offset (0, 0): the landmark sits on the robot, no bearing")
    ratio = math.copysign(math.inf, dy) if dx == 0.0 else dy / dx
    seed = float(wrap_angle(math.atan(ratio) - theta_rad))
    right = float(wrap_angle(math.atan2(dy, dx) - theta_rad))
    return BearingComparison(dx, dy, seed, right, float(wrap_angle(right - seed)))


# --- lambdified twins of ekfslam.core.models ------------------------------------------------------


@dataclass(frozen=True)
class NumericModels:
    """sympy-derived twins of the functions of `ekfslam.core.models`: same names, arguments and
    shapes.

    Angles in the outputs are wrapped to [-π, π) and a landmark on the robot raises
    `DegenerateGeometry`, exactly as in `ekfslam.core.models`, so the two can be compared directly.
    """

    motion: Callable[[ArrayLike, ArrayLike], Array]
    motion_jacobian: Callable[[ArrayLike, ArrayLike], Array]
    motion_control_jacobian: Callable[[ArrayLike], Array]
    motion_noise: Callable[[ArrayLike, ArrayLike], Array]
    observation: Callable[[ArrayLike, ArrayLike], Array]
    observation_jacobians: Callable[[ArrayLike, ArrayLike], tuple[Array, Array]]
    inverse_observation: Callable[[ArrayLike, ArrayLike], Array]
    inverse_observation_jacobians: Callable[[ArrayLike, ArrayLike], tuple[Array, Array]]
    observation_noise: Callable[[float, float], Array]


def _lambdify(args: list, expr: sp.ImmutableMatrix) -> Callable[..., Array]:
    fn = sp.lambdify(args, expr, modules="numpy")
    return lambda *values: np.asarray(fn(*values), dtype=float)


def _check_range(pose: ArrayLike, landmark: ArrayLike) -> None:
    dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
    if not dx * dx + dy * dy > MIN_RANGE_SQUARED:
        raise DegenerateGeometry(
            f"landmark at ({landmark[0]:.6g}, {landmark[1]:.6g}) sits on the robot"
        )


@cache
def numeric_models() -> NumericModels:
    """Lambdify every derived model and Jacobian (numpy), wrapped to the signatures of models.py."""
    mot, obs, inv = motion_model(), observation_model(), inverse_observation_model()
    f = _lambdify([POSE, CONTROL], mot.value)
    G = _lambdify([POSE, CONTROL], mot.jacobian_pose)
    V = _lambdify([POSE], mot.jacobian_input)
    R = _lambdify([POSE, M_SYMBOLS.tolist()], motion_noise_expr())
    h = _lambdify([POSE, LANDMARK], obs.value)
    H_pose = _lambdify([POSE, LANDMARK], obs.jacobian_pose)
    H_landmark = _lambdify([POSE, LANDMARK], obs.jacobian_input)
    g = _lambdify([POSE, MEASUREMENT], inv.value)
    g_pose = _lambdify([POSE, MEASUREMENT], inv.jacobian_pose)
    g_z = _lambdify([POSE, MEASUREMENT], inv.jacobian_input)
    Q = _lambdify([sigma_r, sigma_phi], observation_noise_expr())

    def motion(pose: ArrayLike, u: ArrayLike) -> Array:
        out = f(pose, u).ravel()
        out[2] = wrap_angle(float(out[2]))
        return out

    def observation(pose: ArrayLike, landmark: ArrayLike) -> Array:
        _check_range(pose, landmark)
        out = h(pose, landmark).ravel()
        out[1] = wrap_angle(float(out[1]))
        return out

    def observation_jacobians(pose: ArrayLike, landmark: ArrayLike) -> tuple[Array, Array]:
        _check_range(pose, landmark)
        return H_pose(pose, landmark), H_landmark(pose, landmark)

    return NumericModels(
        motion=motion,
        motion_jacobian=G,
        motion_control_jacobian=V,
        # models.motion_noise symmetrises V M Vᵀ, which is V sym(M) Vᵀ
        motion_noise=lambda pose, M: R(pose, 0.5 * (np.asarray(M) + np.asarray(M).T)),
        observation=observation,
        observation_jacobians=observation_jacobians,
        inverse_observation=lambda pose, z: g(pose, z).ravel(),
        inverse_observation_jacobians=lambda pose, z: (g_pose(pose, z), g_z(pose, z)),
        observation_noise=lambda s_r, s_phi: Q(float(s_r), float(s_phi)),
    )


# --- the lifts F_x (eq. 8) and F_x,j (eq. 14) ---------------------------------------------------


def _check_slot(n_landmarks: int, j: int | None = None) -> None:
    if n_landmarks < 0:
        raise ValueError(f"the number of landmarks must be >= 0, got {n_landmarks}")
    if j is not None and not 0 <= j < n_landmarks:
        raise ValueError(f"landmark slot j={j} is outside the map of {n_landmarks} landmarks")


def lift_matrix_numeric(n_landmarks: int) -> Array:
    """F_x, eq. (8): (3, 3 + 2n), the identity on the pose columns and zeros elsewhere."""
    _check_slot(n_landmarks)
    return np.eye(3, 3 + 2 * n_landmarks)


def landmark_lift_matrix_numeric(n_landmarks: int, j: int) -> Array:
    """F_x,j of eq. (14): (5, 3 + 2n), picking the pose and landmark j (0-based).

    Landmark j occupies the state indices 3 + 2j and 4 + 2j (eq. 1).
    """
    _check_slot(n_landmarks, j)
    F = np.zeros((5, 3 + 2 * n_landmarks))
    F[:3, :3] = np.eye(3)
    F[3:, 3 + 2 * j : 5 + 2 * j] = np.eye(2)
    return F


def lift_matrix(n_landmarks: int) -> sp.ImmutableMatrix:
    """F_x, eq. (8), as an exact sympy matrix of shape (3, 2n + 3)."""
    return sp.ImmutableMatrix(lift_matrix_numeric(n_landmarks).astype(int))


def landmark_lift_matrix(n_landmarks: int, j: int) -> sp.ImmutableMatrix:
    """F_x,j of eq. (14) as an exact sympy matrix of shape (5, 2n + 3); j is 0-based."""
    return sp.ImmutableMatrix(landmark_lift_matrix_numeric(n_landmarks, j).astype(int))


def lifted_motion_jacobian(n_landmarks: int) -> sp.ImmutableMatrix:
    """The full-state G_t (2n+3 square): I + F_xᵀ (G - I) F_x, G top-left and identity elsewhere."""
    F = lift_matrix(n_landmarks)
    G = motion_model().jacobian_pose
    return sp.ImmutableMatrix(sp.eye(F.cols) + F.T * (G - sp.eye(3)) * F)


def lifted_observation_jacobian(n_landmarks: int, j: int) -> sp.ImmutableMatrix:
    """The full-state H of eq. (14), (2, 2n+3): the derived 2x5 block times F_x,j."""
    return sp.ImmutableMatrix(derived_observation_jacobian() * landmark_lift_matrix(n_landmarks, j))


@dataclass(frozen=True)
class LiftShapes:
    """What sympy makes of the seed's lifts for a map of `n_landmarks`; shapes are (rows, cols).

    A shape of None means sympy refused the product; the matching ``*_error`` field holds its
    ShapeError message (empty when the product is defined).
    """

    n_landmarks: int
    state_size: int  # 2N + 3
    F_x: tuple[int, int]  # eq. (8)
    F_x_j: tuple[int, int] | None  # eq. (14); None when there is no landmark to pick
    seed_G: tuple[int, int] | None  # eq. (7): F_x g F_xᵀ with the 3x3 g
    seed_G_error: str
    seed_R: tuple[int, int] | None  # eq. (9): F_x R F_xᵀ with the 3x3 R
    seed_R_error: str
    pose_block_of_full: tuple[int, int]  # F_x A F_xᵀ for a full-size A: always (3, 3)
    seed_H: tuple[int, int] | None  # eq. (14): (2x5) F_x,j for landmark 0, well defined
    lifted_R: tuple[int, int]  # F_xᵀ R F_x
    lifted_R_is_padded: bool  # F_xᵀ R F_x == diag(R, 0)
    lifted_G: tuple[int, int]  # I + F_xᵀ (g - I) F_x
    lifted_G_is_block_diagonal: bool  # I + F_xᵀ (g - I) F_x == diag(g, I)
    transposed_G_drops_landmarks: bool  # F_xᵀ g F_x has zeros on the landmark diagonal


def _try_shape(make: Callable[[], sp.MatrixBase]) -> tuple[tuple[int, int] | None, str]:
    try:
        return make().shape, ""
    except sp.ShapeError as error:
        return None, str(error)


@cache
def seed_lift_shapes(n_landmarks: int) -> LiftShapes:
    """Build the seed's lifts of eqs. (7), (9) and (14) with sympy and record what is defined.

    F_x is 3 x (2N+3), so F_x X F_xᵀ needs X to be (2N+3) x (2N+3) and then gives 3x3: it
    *extracts* the pose block. With the 3x3 g of eq. (7) or the 3x3 R of eq. (9) the product is
    undefined for every N >= 1 (sympy raises ShapeError); only for N = 0, where F_x = I, is it
    defined. The lifts that do what the seed means are F_xᵀ R F_x and I + F_xᵀ (g - I) F_x, both
    (2N+3) x (2N+3). Eq. (14), H = (2x5) F_x,j, is right as printed.
    """
    F = lift_matrix(n_landmarks)
    n = F.cols
    F_j = landmark_lift_matrix(n_landmarks, 0) if n_landmarks else None
    g = motion_model().jacobian_pose
    R = sp.ImmutableMatrix(3, 3, sp.symbols("R_0:3(0:3)", real=True))
    seed_G, seed_G_error = _try_shape(lambda: F * g * F.T)
    seed_R, seed_R_error = _try_shape(lambda: F * R * F.T)
    lifted_R = F.T * R * F
    lifted_G = sp.eye(n) + F.T * (g - sp.eye(3)) * F
    transposed_G = F.T * g * F
    landmark_diagonal = [transposed_G[i, i] for i in range(3, n)]
    return LiftShapes(
        n_landmarks=n_landmarks,
        state_size=n,
        F_x=F.shape,
        F_x_j=F_j.shape if F_j is not None else None,
        seed_G=seed_G,
        seed_G_error=seed_G_error,
        seed_R=seed_R,
        seed_R_error=seed_R_error,
        pose_block_of_full=(F * sp.MatrixSymbol("A", n, n) * F.T).shape,
        seed_H=(derived_observation_jacobian() * F_j).shape if F_j is not None else None,
        lifted_R=lifted_R.shape,
        lifted_R_is_padded=lifted_R == sp.diag(R, sp.zeros(n - 3, n - 3)),
        lifted_G=lifted_G.shape,
        lifted_G_is_block_diagonal=lifted_G == sp.diag(g, sp.eye(n - 3)),
        transposed_G_drops_landmarks=n > 3 and all(d == 0 for d in landmark_diagonal),
    )
