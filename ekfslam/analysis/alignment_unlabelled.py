"""Which true landmark each estimated one is, from the maps alone: for eq. (17) without ids.

`ekfslam.analysis.alignment.align` matches landmarks by id. A map built with the ids hidden
names its landmarks 0, 1, 2 ...; when no association mapping to true ids is at hand (a run
whose detections carry none), the estimated and true landmarks are matched from their
positions, in two steps:

1. A robust fit. Every ordered pair of estimated landmarks (i, k) is laid onto every pair of
   true landmarks (a, b) as far apart (within `pair_tolerance`), which fixes a rigid transform;
   each hypothesis is scored by the truncated cost Σ_i min(d_i, c) over all estimated landmarks,
   d_i the distance to the nearest true landmark after the transform and c the cut-off: a
   landmark far from every true one costs c, however far, so outliers and duplicates do not
   steer the fit (RANSAC over pairs, with an MSAC score: Torr & Zisserman, CVIU 78, 2000). The
   search is exhaustive, so the answer does not depend on a random seed. A map symmetric under
   a turn (the seed's arena under half a turn) fits equally well turned; of the fits within c
   of the best, the one that turns least is taken (the estimate is in the believed start's
   frame, which differs from the true one by the start error).
2. Nearest neighbours. Under the best transform each estimated landmark is matched to its
   nearest true landmark when they are within c of each other and each is the other's nearest
   (mutual: a true landmark is matched once), and the matches refit the transform by least
   squares; two rounds of matching and refitting settle it.

`align` then minimises eq. (17) over the matched landmarks (keyed by their true ids), and the
output says the matching was this one (`MATCHED_BY_NEAREST`), not an association mapping.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ekfslam.analysis._alignment_solver import weighted_kabsch
from ekfslam.errors import AlignmentError
from ekfslam.geometry import transform_points

Array = NDArray[np.float64]

#: How eq. (17) matched landmarks, said in the output.
MATCHED_BY_NEAREST = (
    "estimated landmarks matched to true ones by nearest neighbour after a robust fit "
    "(RANSAC over pairs)"
)


@dataclass(frozen=True)
class NearestMatch:
    """The matching `match_by_position` found.

    mapping : {estimated id: true id}, one-to-one. transform : (x0, y0, θ0) of the robust fit,
    world = R(θ0) estimate + (x0, y0). cutoff : m, the c of the truncated cost. hypotheses :
    pair hypotheses scored. unmatched : estimated ids with no true landmark within c.
    """

    mapping: dict[int, int]
    transform: Array
    cutoff: float
    hypotheses: int
    unmatched: list[int]


def match_by_position(
    estimated: Mapping[Any, ArrayLike],
    truth: Mapping[Any, ArrayLike],
    cutoff: float | None = None,
    pair_tolerance: float | None = None,
) -> NearestMatch:
    """Match estimated landmarks to true ones by position (see the module).

    estimated, truth : {id: (x, y)}, m; at least 2 of each.
    cutoff : m, the truncated cost's c and the farthest a match may be. None: half the median
        distance between true landmarks and their nearest true neighbour (a landmark nearer
        its match than that cannot be taken for the neighbour).
    pair_tolerance : m, how much a pair's length may differ between the maps; None: 2 c.
    """
    est_ids, X = _as_points(estimated, "estimated")
    true_ids, Y = _as_points(truth, "true")
    gaps = np.hypot(*(Y[:, None, :] - Y[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(gaps, np.inf)
    c = float(np.median(gaps.min(axis=1))) / 2.0 if cutoff is None else float(cutoff)
    tol = 2.0 * c if pair_tolerance is None else float(pair_tolerance)
    if not (c > 0 and tol > 0):
        raise AlignmentError(f"cutoff and pair_tolerance must be positive, got {c} and {tol}")
    all_params, all_costs = [], []
    i, k = np.triu_indices(len(X), 1)
    a, b = np.nonzero(np.isfinite(gaps))  # ordered pairs of true landmarks: both directions
    d_est = np.hypot(*(X[i] - X[k]).T)
    for p in range(len(i)):
        fits = np.nonzero(np.abs(gaps[a, b] - d_est[p]) <= tol)[0]
        if len(fits) == 0:
            continue
        params = _pair_transforms(X[i[p]], X[k[p]], Y[a[fits]], Y[b[fits]])  # (F, 3)
        all_params.append(params)
        all_costs.append(_truncated_costs(params, X, Y, c))
    if not all_params:
        raise AlignmentError("no pair of estimated landmarks is as far apart as a true pair")
    params, costs = np.concatenate(all_params), np.concatenate(all_costs)
    tried = len(costs)
    # a map symmetric under a turn fits as well both ways; the estimate is in the frame of the
    # start the robot believed, so among fits within one landmark's cost c of the best, the
    # one that turns least is taken
    near = np.nonzero(costs <= costs.min() + c)[0]
    best = params[near[np.argmin(np.abs(np.angle(np.exp(1j * params[near, 2]))))]]
    pairs: list[tuple[int, int]] = []
    for _ in range(2):
        pairs = _mutual_nearest(best, X, Y, c)
        if len(pairs) >= 2:
            e, t = (np.array(v) for v in zip(*pairs, strict=True))
            best = weighted_kabsch(X[e], Y[t], np.ones(len(e)))
    mapping = {est_ids[e]: true_ids[t] for e, t in pairs}
    unmatched = sorted(set(est_ids) - mapping.keys())
    return NearestMatch(mapping, best, c, tried, unmatched)


def _as_points(points: Mapping[Any, ArrayLike], which: str) -> tuple[list[int], Array]:
    keys = sorted(points, key=int)  # ids and rows in one order: "10" sorts before "9" as text
    if len(keys) < 2:
        raise AlignmentError(f"matching by position needs at least 2 {which} landmarks")
    ids = [int(key) for key in keys]
    P = np.array([np.asarray(points[key], dtype=float).reshape(2) for key in keys])
    if not np.isfinite(P).all():
        raise AlignmentError(f"{which} landmark positions must be finite")
    return ids, P


def _pair_transforms(x1: Array, x2: Array, y1: Array, y2: Array) -> Array:
    """(F, 3) rigid transforms taking x1 to each y1 and the direction x1→x2 onto y1→y2."""
    dx, dy = x2 - x1, y2 - y1
    theta = np.arctan2(dy[:, 1], dy[:, 0]) - np.arctan2(dx[1], dx[0])
    c, s = np.cos(theta), np.sin(theta)
    tx = y1[:, 0] - (c * x1[0] - s * x1[1])
    ty = y1[:, 1] - (s * x1[0] + c * x1[1])
    return np.column_stack([tx, ty, theta])


def _truncated_costs(params: Array, X: Array, Y: Array, c: float) -> Array:
    """(F,) Σ_i min(d_i, c) of each transform, d_i: estimated i to its nearest true landmark."""
    cos, sin = np.cos(params[:, 2])[:, None], np.sin(params[:, 2])[:, None]
    mx = cos * X[:, 0] - sin * X[:, 1] + params[:, :1]  # (F, N)
    my = sin * X[:, 0] + cos * X[:, 1] + params[:, 1:2]
    d = np.hypot(mx[:, :, None] - Y[:, 0], my[:, :, None] - Y[:, 1])  # (F, N, M)
    return np.minimum(d.min(axis=2), c).sum(axis=1)


def _nearest(params: Array, X: Array, Y: Array) -> tuple[Array, Array]:
    moved = transform_points(params, X)
    d = np.hypot(*(moved[:, None, :] - Y[None, :, :]).transpose(2, 0, 1))  # (N, M)
    return d, d.argmin(axis=1)


def _mutual_nearest(params: Array, X: Array, Y: Array, c: float) -> list[tuple[int, int]]:
    d, to_true = _nearest(params, X, Y)
    to_est = d.argmin(axis=0)
    return [(e, int(t)) for e, t in enumerate(to_true) if to_est[t] == e and d[e, t] <= c]
