"""The lab's checks that need the replay and the alignment: the replay loop (exercise 8,
notebook 06) and the alignment of eq. (17) (exercise 9, notebook 07); and notebook 07's
prediction of the realistic robot's error budget (`check_sources_above`).

They live on the analysis floor because they hold the student's answer to `ekfslam.pipeline.replay`
and `ekfslam.analysis.alignment`, which the teaching floor may not import; the verdict machinery
is still `ekfslam.teaching.verdicts`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ekfslam.analysis.alignment import Alignment, align, align_least_squares, align_mean_distance
from ekfslam.analysis.error_budget import ErrorBudget
from ekfslam.analysis.replay_mistakes import WatchedEKF, diagnose
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.noise import NoiseConfig, default_config, default_noise
from ekfslam.geometry import rotation, wrap_angle
from ekfslam.logs.runlog import RunLog
from ekfslam.pipeline import replay
from ekfslam.teaching.verdicts import RNG_SEED, Array, Wrong, as_array, attempt, close

#: a Table 1 row: the transform of eq. (17) and the mean distance it leaves
ROW = ("x0", "y0", "theta0", "mean_error")

# --- exercise 8: the replay loop -----------------------------------------------------------------


def landmarks_of(ekf: EKFSLAM) -> dict[int, Array]:
    """{id: (2,)} the filter's map, as `ReplayResult.landmarks` holds it."""
    return {int(i): ekf.mu[3 + 2 * j : 5 + 2 * j].copy() for j, i in enumerate(ekf.landmark_ids)}


def table1_row(landmarks: dict[int, Array], run: RunLog) -> Array:
    """(x0, y0, θ0, mean error) of eq. (17) for a map of the run: its Table 1 row."""
    a: Alignment = align(landmarks, run.meta.tag_map)
    return np.array([a.x0, a.y0, a.theta0, a.mean_error])


def check_replay(
    replay_loop: Callable[[RunLog, EKFSLAM, NoiseConfig], object], run: RunLog
) -> bool:
    """Exercise 8: `replay_loop(run, ekf, noise)` drives the filter `ekf` (started at the run's
    nominal pose) over the run's controls and detections; afterwards its state and the Table 1
    row of its map must be `ekfslam.replay(run)`'s to 1e-9. A loop that differs is replayed
    against the typical mistakes (`ekfslam.analysis.replay_mistakes`) to name its one."""

    def check() -> None:
        ekf = WatchedEKF(run.meta.nominal_start, None, default_config(run))
        replay_loop(run, ekf, default_noise(run))
        want = replay(run)
        got, ref = ekf.counts, want.counts
        same = ekf.mu.shape == want.mu.shape and close(ekf.mu, want.mu)
        if not same or got.predictions != ref.predictions:
            mistake = diagnose(run, default_noise(run), ekf.mu, got.predictions)
            if mistake is not None:
                raise Wrong(f"your numbers are those of a loop that {mistake}")
        seen = got.initialised + got.accepted + got.rejected + got.refused + got.reinitialised
        n = len(run.detections.t)
        if seen != n:
            raise Wrong(f"your loop fed {seen} of the run's {n} detections to ekf.update.")
        if got.predictions != ref.predictions:
            raise Wrong(
                f"your loop made {got.predictions} predictions: predict every control interval "
                "piece by piece, split at the detections inside it (each piece before the "
                "detection at its end), and on to the last control."
            )
        if ekf.mu.shape != want.mu.shape or not close(ekf.mu[:3], want.mu[:3]):
            raise Wrong(
                "your final pose differs from the replay's: is each detection applied once the "
                "pose is predicted up to its time, each piece with u = twist·dt and its own R "
                "(a wrong R changes the gains, so the means too)?"
            )
        if not close(ekf.mu, want.mu):
            raise Wrong("your map differs from the replay's: is each detection fed at its time?")
        if not close(ekf.Sigma, want.Sigma, atol=1e-12):
            raise Wrong(
                "your Σ differs from the replay's: each piece's R is V (M dt) Vᵀ at the heading "
                "before the step (eq. 9)."
            )
        if not close(table1_row(landmarks_of(ekf), run), table1_row(want.landmarks, run)):
            raise Wrong("your map's Table 1 row differs from the replay's.")

    return attempt("8", check)


# --- exercise 9: the alignment of eq. (17) --------------------------------------------------------


def _maps(rng: np.random.Generator) -> list[tuple[Array, Array]]:
    """(estimated X, true Y), (N, 2) each: an arena of 8 tags, the estimate turned, shifted and
    noisy; the last one with a tag 30 cm off, where least squares and eq. (17) part by cm."""
    Y = rng.uniform(-0.75, 0.75, (8, 2))
    out = []
    for k, (x0, y0, th) in enumerate(
        ((-0.073, 0.097, 0.14), (0.02, -0.05, -0.2), (0.0, 0.06, 0.1))
    ):
        X = (Y - [x0, y0]) @ rotation(th) + rng.normal(0, 0.02, Y.shape)  # R(θ)ᵀ (Y - t)
        if k == 2:
            X[4] += [0.30, 0.0]
        out.append((X, Y.copy()))
    return out


def check_alignment(align_map: Callable[[Array, Array], object]) -> bool:
    """Exercise 9: `align_map(X (N, 2), Y (N, 2)) -> (x0, y0, θ0)`, the transform with
    Y ≈ R(θ0) X + (x0, y0) that minimises eq. (17), the mean distance (the answer is
    `ekfslam.analysis.alignment.align_mean_distance`), to 1e-6 m and rad."""

    def check() -> None:
        for X, Y in _maps(np.random.default_rng(RNG_SEED)):
            got = as_array(align_map(X.copy(), Y.copy()), (3,), "your (x0, y0, θ0)")
            got[2] = wrap_angle(float(got[2]))
            want = align_mean_distance(X, Y)
            params = np.array([want.x0, want.y0, want.theta0])
            if close(got, params, atol=1e-6):
                continue
            if close(got[2], -params[2], atol=1e-6):
                raise Wrong("θ0 has the wrong sign: the true map is R(θ0) X + (x0, y0).")
            ls = align_least_squares(X, Y)
            if close(got, [ls.x0, ls.y0, ls.theta0], atol=1e-6):
                raise Wrong(
                    "you minimised the squared distances (least squares), not eq. (17)'s mean "
                    "distance: they part when one tag is far off."
                )
            moved = X @ rotation(got[2]).T + got[:2]
            mine = float(np.mean(np.hypot(*(moved - Y).T)))
            if mine > want.mean_error + 1e-9:
                raise Wrong("your transform leaves a larger mean distance than eq. (17)'s minimum.")
            raise Wrong("your transform is not the one of eq. (17): world = R(θ0) X + (x0, y0).")

    return attempt("9", check)


# --- notebook 07: the realistic robot's error budget, predicted then tested -----------------------


def check_sources_above(guess: object, budget: ErrorBudget, threshold: float = 0.01) -> bool:
    """The prediction of notebook 07: the names of the error sources that alone cost more than
    `threshold` (m) of map error in `budget`. Told after the budget is shown, so the verdict
    names each source put on the wrong side with what it costs alone."""
    if guess is None:
        print(
            f"Not answered yet: put the names you expect above {100 * threshold:g} cm in a set "
            "and run again."
        )
        return False
    names = {r.source for r in budget.rows}
    picked = {guess} if isinstance(guess, str) else set(guess)
    unknown = sorted(str(g) for g in picked - names)
    if unknown:
        print(f"Not yet: {unknown} are not sources of the table; they are {sorted(names)}.")
        return False
    wrong = [r for r in budget.rows if (r.source in picked) != (r.alone > threshold)]
    if not wrong:
        print(
            f"Right: on the {budget.trajectory} these and only these cost over "
            f"{100 * threshold:g} cm alone."
        )
        return True
    for r in wrong:
        side = "above" if r.source in picked else "below"
        print(
            f"Not quite: you put {r.source} {side} {100 * threshold:g} cm; alone it costs "
            f"{1000 * r.alone:.0f} mm on the {budget.trajectory}."
        )
    return False
