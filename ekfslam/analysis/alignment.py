"""Map alignment: the rigid transform that best lays the estimated map onto the true one, eq. (17).

The filter builds its map in the frame the robot *believed* it started in. To score the map, and
to recover where the robot really started, we look for the SE(2) transform (x0, y0, θ0) with

    world = R(θ0) @ estimate + (x0, y0),

that minimises the seed's eq. (17), the mean Euclidean distance between the transformed estimated
landmarks X_i and the true ones Y_i::

    f(x, y, θ) = (1/N) Σ_i ‖R(θ) X_i + (x, y) − Y_i‖.

It is a sum of norms, not of squares: one badly placed landmark pulls on the answer with a force of
at most 1/N, whereas in least squares it pulls in proportion to its error. The price is that f is
not smooth wherever some landmark fits exactly, and its minimiser often sits on exactly such a
kink (for 8 landmarks with 5 cm noise, about a third of the time), so we treat that case
explicitly instead of hoping a generic optimiser gets there.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam import checks
from ekfslam.analysis._alignment_solver import distances, minimise, weighted_kabsch
from ekfslam.errors import AlignmentError
from ekfslam.geometry import compose, rotation, transform_points, wrap_angle
from ekfslam.plausibility import MAX_POSITION

Method = Literal["mean_distance", "least_squares"]
#: The objectives `align` knows (`Method`).
METHODS: tuple[str, ...] = ("mean_distance", "least_squares")
Array = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class Alignment:
    """The result of aligning an estimated map to the true one, eq. (17).

    Attributes
    ----------
    x0, y0 : float
        Translation (m) of the transform ``world = R(theta0) @ estimate + (x0, y0)``.
    theta0 : float
        Rotation (rad) of that transform, wrapped to [-π, π).
    ids : ndarray of int, shape (N,)
        The matched landmark ids, sorted (0..N-1 when the inputs were plain arrays).
    aligned : ndarray, shape (N, 2)
        The estimated landmarks after the transform (m), in ``ids`` order.
    truth : ndarray, shape (N, 2)
        The true landmark positions (m), in ``ids`` order.
    errors : ndarray, shape (N,)
        Per-landmark distance (m) between ``aligned`` and ``truth``.
    mean_error : float
        Mean of ``errors`` (m): the value of eq. (17) at the returned transform.
    rmse : float
        Root mean square of ``errors`` (m): what least squares minimises.
    method : {"mean_distance", "least_squares"}
        Which objective was minimised.
    iterations : int
        Solver iterations (IRLS plus Newton steps); 0 for the closed-form least squares.
    converged : bool
        True when the result passed the optimality check (see `align_mean_distance`).
    """

    x0: float
    y0: float
    theta0: float
    ids: NDArray[np.int_]
    aligned: Array
    truth: Array
    errors: Array
    mean_error: float
    rmse: float
    method: Method
    iterations: int
    converged: bool

    @property
    def transform(self) -> Array:
        """The transform as an array (x0, y0, θ0), shape (3,), in m, m, rad."""
        return np.array([self.x0, self.y0, self.theta0])

    def apply(self, points: ArrayLike) -> Array:
        """Map points (M, 2) from the estimate's frame to the world: R(θ0) p + (x0, y0)."""
        points = checks.rows(points, "Alignment.apply: points", 2, bound=MAX_POSITION)
        return transform_points(self.transform, points)

    def apply_pose(self, pose: ArrayLike) -> Array:
        """Map a robot pose (x, y, θ) from the estimate's frame to the world, shape (3,).

        The position is rotated by θ0 and translated by (x0, y0); θ0 is added to the heading,
        which is then wrapped to [-π, π).
        """
        return compose(self.transform, checks.pose(pose, "Alignment.apply_pose: pose"))

    def start_pose(self, nominal_start: ArrayLike) -> Array:
        """The robot's true start pose (x, y, θ), shape (3,), given the start it believed in.

        The filter placed its first pose at `nominal_start` and built the map around it, so the
        same transform that lays the map onto the world carries that pose to where the robot
        really stood.
        """
        return compose(self.transform, checks.pose(nominal_start, "Alignment.start_pose: pose"))


def mean_distance_objective(params: ArrayLike, X: ArrayLike, Y: ArrayLike) -> float:
    """Eq. (17): the mean distance (m) between R(θ) X_i + (x, y) and Y_i.

    Parameters
    ----------
    params : array_like, shape (3,)
        The transform (x, y, θ) in m, m, rad.
    X, Y : array_like, shape (N, 2)
        Estimated and true landmark positions (m), row i of each being the same landmark.
    """
    return float(np.mean(distances(np.asarray(params, dtype=float), _points(X), _points(Y))))


def align_least_squares(estimated: ArrayLike, truth: ArrayLike) -> Alignment:
    """Closed-form least-squares alignment (2-D Kabsch/Umeyama, no scale, proper rotation).

    Minimises Σ_i ‖R(θ) X_i + (x, y) − Y_i‖², the squared cousin of eq. (17).

    Parameters
    ----------
    estimated, truth : array_like, shape (N, 2)
        Estimated and true landmark positions (m), row i of each being the same landmark; N >= 2.
    """
    X, Y = _check_pair(estimated, truth)
    params = weighted_kabsch(X, Y, np.ones(len(X)))
    return _result(params, X, Y, np.arange(len(X)), "least_squares", 0, True)


def align_mean_distance(
    estimated: ArrayLike, truth: ArrayLike, *, tol: float = 1e-12, max_iterations: int = 1000
) -> Alignment:
    """Align by minimising eq. (17), the mean Euclidean distance, to convergence.

    From the least-squares solution, iteratively reweighted least-squares steps (Weiszfeld
    weights 1/max(d_i, ε), ε = tol × map size; no step increases eq. 17) bring us near the
    minimum, and Newton's method finishes, in one of two forms:

    * kink, tried first: the best-fitting landmark k is pinned (d_k = 0) and θ alone is solved.
      This is the minimum when the other landmarks' pull on the translation has norm <= 1 (the
      subgradient of ‖r_k‖ absorbs it), the slope along the pinned family is zero and its
      curvature positive. If not, we step off the kink downhill before the smooth finish;
    * smooth: damped Newton on (x, y, θ), with an IRLS step wherever Newton does not descend,
      checked by a vanishing Newton step and a positive-definite Hessian. If it ends on another
      kink, that kink is checked as above.

    The solver works on centred maps scaled to unit size, so its tolerances mean the same for
    a 1.5 m arena and a 100 m campus, wherever the origin is.

    Parameters
    ----------
    estimated, truth : array_like, shape (N, 2)
        Estimated and true landmark positions (m), row i of each being the same landmark; N >= 2.
    tol : float
        Stop when a step changes the parameters (translation relative to the map size, and θ in
        rad) by less than this, or no longer lowers the objective.
    max_iterations : int
        Upper bound on IRLS plus Newton steps.

    Returns
    -------
    Alignment
        ``converged`` is True when the optimality check passed; ``iterations`` counts IRLS and
        Newton steps. With two landmarks the minimiser is not unique (any shift along the line
        between them is equally good); we return the least-squares one, which is among them.
    """
    X, Y = _check_pair(estimated, truth)
    checks.real(tol, "align_mean_distance: tol", lo=0.0)
    checks.whole(max_iterations, "align_mean_distance: max_iterations", lo=1)
    x_bar, y_bar = X.mean(axis=0), Y.mean(axis=0)
    size = _spread(Y) or _spread(X) or 1.0
    tol = max(tol, 1e-15)  # it is also the IRLS weight cap, 1/tol: it must stay finite
    params, used, converged = minimise((X - x_bar) / size, (Y - y_bar) / size, tol, max_iterations)
    # R (X − x̄)/s + t' = (Y − ȳ)/s  ⇔  R X + (s t' + ȳ − R x̄) = Y
    t = size * params[:2] + y_bar - rotation(params[2]) @ x_bar
    transform = np.array([t[0], t[1], params[2]])
    return _result(transform, X, Y, np.arange(len(X)), "mean_distance", used, converged)


def align(
    estimated: Mapping[Any, ArrayLike] | Any,
    truth: Mapping[Any, ArrayLike] | Any,
    method: Method = "mean_distance",
) -> Alignment:
    """Align an estimated map to the true map, matching landmarks by id; eq. (17) by default.

    Parameters
    ----------
    estimated, truth : mapping {landmark id: (x, y)}
        Anything with ``.items()``; positions in m. Only ids present in both are used.
    method : {"mean_distance", "least_squares"}
        ``"mean_distance"`` minimises eq. (17); ``"least_squares"`` the sum of squared distances.

    Raises
    ------
    AlignmentError
        When fewer than two landmarks are in common, or `method` is unknown.
    """
    solvers = {"mean_distance": align_mean_distance, "least_squares": align_least_squares}
    checks.choice(method, "align: method", METHODS)
    est = checks.points_by_id(estimated, "align: estimated")
    true = checks.points_by_id(truth, "align: truth")
    common = sorted(est.keys() & true.keys())
    if len(common) < 2:
        raise AlignmentError(
            f"map alignment needs at least 2 landmarks in common, found {len(common)}: "
            f"estimated ids {_brief(est)}, true ids {_brief(true)}"
        )
    X = np.array([est[i] for i in common])
    Y = np.array([true[i] for i in common])
    result = solvers[method](X, Y)
    ids = np.array(common, dtype=int)
    ids.setflags(write=False)
    return replace(result, ids=ids)


# --- plumbing ---------------------------------------------------------------------------------


def _result(
    params: Array,
    X: Array,
    Y: Array,
    ids: NDArray[np.int_],
    method: Method,
    iterations: int,
    converged: bool,
) -> Alignment:
    theta = float(wrap_angle(float(params[2])))
    transform = np.array([params[0], params[1], theta])
    aligned = transform_points(transform, X)
    errors = np.hypot(*(aligned - Y).T)
    truth = Y.copy()
    for array in (ids, aligned, truth, errors):
        array.setflags(write=False)
    return Alignment(
        x0=float(params[0]),
        y0=float(params[1]),
        theta0=theta,
        ids=ids,
        aligned=aligned,
        truth=truth,
        errors=errors,
        mean_error=float(errors.mean()),
        rmse=float(np.sqrt(np.mean(errors**2))),
        method=method,
        iterations=int(iterations),
        converged=bool(converged),
    )


def _points(P: ArrayLike) -> Array:
    return np.asarray(P, dtype=float).reshape(-1, 2)


def _check_pair(estimated: ArrayLike, truth: ArrayLike) -> tuple[Array, Array]:
    what = "landmark positions (x, y) in m"
    X = checks.array(
        estimated, "align: estimated", (None, 2), what, finite=False, bound=MAX_POSITION
    )
    Y = checks.array(truth, "align: truth", (None, 2), what, finite=False, bound=MAX_POSITION)
    if X.ndim != 2 or X.shape[1:] != (2,) or X.shape != Y.shape:
        raise AlignmentError(
            f"estimated and true landmarks must both have shape (N, 2); got {X.shape} and {Y.shape}"
        )
    if len(X) < 2:
        raise AlignmentError(f"map alignment needs at least 2 landmarks, got {len(X)}")
    if not (np.isfinite(X).all() and np.isfinite(Y).all()):
        raise AlignmentError("landmark positions must be finite; found NaN or infinity")
    for name, P in (("true", Y), ("estimated", X)):
        if _spread(P) <= ONE_POINT * max(1.0, float(np.abs(P).max())):
            raise AlignmentError(
                f"the {len(P)} {name} landmarks all lie at one point {P[0].tolist()}: eq. (17) "
                "cannot find the map's rotation from them (it is undetermined)"
            )
    return X, Y


#: A map whose points spread less than this (relative to their size) is at one point.
ONE_POINT = 1e-9


def _spread(P: Array) -> float:
    """Size of a map (m): the RMS distance of its points from their centroid."""
    return float(np.sqrt(np.mean(np.sum((P - P.mean(axis=0)) ** 2, axis=1))))


def _brief(mapping: Mapping[int, Any], limit: int = 10) -> str:
    ids = sorted(mapping)
    shown = ", ".join(str(i) for i in ids[:limit])
    more = f", … ({len(ids)} in all)" if len(ids) > limit else ""
    return f"[{shown}{more}]"
