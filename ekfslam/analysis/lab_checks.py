"""The lab's checks that need the replay and the alignment: the replay loop (exercise 8,
notebook 06) and the alignment of eq. (17) (exercise 9, notebook 07), as exercises of
`ekfslam.teaching.verdicts`; and notebook 07's prediction of the realistic robot's error budget
(`check_sources_above`).

They live on the analysis floor because they hold the student's answer to `ekfslam.pipeline.replay`
and `ekfslam.analysis.alignment`, which the teaching floor may not import; the verdict machinery
is still `ekfslam.teaching.verdicts`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ekfslam.analysis.alignment import Alignment, align, align_least_squares, align_mean_distance
from ekfslam.analysis.error_budget import ErrorBudget
from ekfslam.analysis.replay_mistakes import diagnose
from ekfslam.analysis.watched_filter import FilterUnderTest, WatchedEKF
from ekfslam.core import kinematics, models
from ekfslam.core.filter.ekf import EKFSLAM
from ekfslam.core.noise import NoiseConfig, default_config, default_noise
from ekfslam.geometry import rotation, wrap_angle
from ekfslam.logs.runlog import Controls, Detections, RunLog, read_run
from ekfslam.pipeline import replay
from ekfslam.places import seed_run
from ekfslam.teaching.verdicts import (
    Array,
    Exercise,
    NotDone,
    Wrong,
    as_array,
    attempt,
    close,
)

#: a Table 1 row: the transform of eq. (17) and the mean distance it leaves
ROW = ("x0", "y0", "theta0", "mean_error")

# --- exercise 8: the replay loop -----------------------------------------------------------------


def landmarks_of(ekf: EKFSLAM | dict) -> dict[int, Array]:
    """{id: (2,)} the filter's map (or a `FilterUnderTest.snapshot`'s), as
    `ReplayResult.landmarks` holds it."""
    mu, ids = (
        (ekf["mu"], ekf["landmark_ids"]) if isinstance(ekf, dict) else (ekf.mu, ekf.landmark_ids)
    )
    return {int(i): np.asarray(mu[3 + 2 * j : 5 + 2 * j]).copy() for j, i in enumerate(ids)}


def table1_row(landmarks: dict[int, Array], run: RunLog) -> Array:
    """(x0, y0, θ0, mean error) of eq. (17) for a map of the run: its Table 1 row."""
    a: Alignment = align(landmarks, run.meta.tag_map)
    return np.array([a.x0, a.y0, a.theta0, a.mean_error])


def replay_case(run: RunLog) -> dict:
    """Exercise 8's case for `run`: the run and what `ekfslam.replay` leaves after it."""
    want = replay(run)
    return {
        "run": run,
        "mu": want.mu,
        "Sigma": want.Sigma,
        "predictions": want.counts.predictions,
        "row": table1_row(want.landmarks, run),
    }


def _replay_cases(rng: np.random.Generator) -> list[dict]:
    """The notebook's case: the seed's octagon with a camera at 7 Hz, so that most detections
    fall between two control times and a loop that does not split the interval there is told."""
    return [replay_case(read_run(seed_run("octagon-2laps-7hz")))]


def _judge_replay(call: Callable, case: dict) -> None:
    run = case["run"]
    config = replace(default_config(run), backend="python")  # graded off the compiler
    state = call(
        ("run", run),
        ("ekf", FilterUnderTest(run.meta.nominal_start, config)),
        ("noise", default_noise(run)),
    )
    got = _counts(state)
    mu, Sigma = _arrays(state)
    seen = sum(got[k] for k in ("initialised", "accepted", "rejected", "refused", "reinitialised"))
    if got["predictions"] == 0 and seen == 0:
        raise NotDone
    same = mu.shape == case["mu"].shape and close(mu, case["mu"])
    if not same or got["predictions"] != case["predictions"]:
        mistake = diagnose(run, default_noise(run), mu, got["predictions"])
        if mistake is not None:
            raise Wrong(f"your numbers are those of a loop that {mistake}")
    n = len(run.detections.t)
    if seen != n:
        raise Wrong(f"your loop fed {seen} of the run's {n} detections to ekf.update.")
    if got["predictions"] != case["predictions"]:
        raise Wrong(
            f"your loop made {got['predictions']} predictions: predict every control interval "
            "piece by piece, split at the detections inside it (each piece before the "
            "detection at its end), and on to the last control."
        )
    if not same and (mu.shape != case["mu"].shape or not close(mu[:3], case["mu"][:3])):
        raise Wrong(
            "your final pose differs from the replay's: is each detection applied once the "
            "pose is predicted up to its time, each piece with u = twist·dt and its own R "
            "(a wrong R changes the gains, so the means too)?"
        )
    if not same:
        raise Wrong("your map differs from the replay's: is each detection fed at its time?")
    if Sigma.shape != case["Sigma"].shape or not close(Sigma, case["Sigma"], atol=1e-12):
        raise Wrong(
            "your Σ differs from the replay's: each piece's R is V (M dt) Vᵀ at the heading "
            "before the step (eq. 9)."
        )
    if not close(table1_row(landmarks_of(state), run), case["row"]):
        raise Wrong("your map's Table 1 row differs from the replay's.")


def _counts(state: object) -> dict[str, int]:
    """The counts of a filter's snapshot, checked (a sandbox's answer is only data)."""
    counts = state.get("counts") if isinstance(state, dict) else None
    if not isinstance(counts, dict) or not all(
        isinstance(counts.get(k), int) and not isinstance(counts.get(k), bool)
        for k in ("predictions", "initialised", "accepted", "rejected", "refused", "reinitialised")
    ):
        raise Wrong("the filter's counts did not come back from your loop.")
    return counts


def _arrays(state: dict) -> tuple[Array, Array]:
    try:
        mu = np.asarray(state["mu"], dtype=float)
        Sigma = np.asarray(state["Sigma"], dtype=float)
        ids = state["landmark_ids"]
    except (KeyError, TypeError, ValueError):
        raise Wrong("the filter's state did not come back from your loop.") from None
    if mu.ndim != 1 or Sigma.shape != (mu.size, mu.size) or not isinstance(ids, list):
        raise Wrong("the filter's state did not come back from your loop.")
    return mu, Sigma


REPLAY_EXERCISE = Exercise(
    "8",
    "replay_loop",
    _replay_cases,
    _judge_replay,
    allowed=lambda: (WatchedEKF, RunLog, Controls, Detections, NoiseConfig, models, kinematics),
    returns=False,
    keeps=(
        "ekfslam.analysis.watched_filter",
        "ekfslam.logs.runlog",
        "ekfslam.core.noise",
        "ekfslam.core.models",
        "ekfslam.core.kinematics",
    ),
    denies=("ekfslam.core.filter.ekf:EKFSLAM.feed", "ekfslam.core.filter.steps:feed"),
)


def check_replay(
    replay_loop: Callable[[RunLog, EKFSLAM, NoiseConfig], object], run: RunLog | None = None
) -> bool:
    """Exercise 8: `replay_loop(run, ekf, noise)` drives the filter `ekf` (started at the run's
    nominal pose) over the run's controls and detections; afterwards its state and the Table 1
    row of its map must be the package's replay's to 1e-9. It is tried on `run` (default: the
    octagon with a 7 Hz camera, whose detections fall between control times). A loop that
    differs is replayed against the typical mistakes (`ekfslam.analysis.replay_mistakes`) to
    name its one."""
    cases = None if run is None else [replay_case(run)]
    return attempt(REPLAY_EXERCISE, replay_loop, cases)


# --- exercise 9: the alignment of eq. (17) --------------------------------------------------------


def _maps(rng: np.random.Generator) -> list[dict]:
    """(estimated X, true Y), (N, 2) each: an arena of 8 tags, the estimate turned, shifted and
    noisy; the last one with a tag 30 cm off, where least squares and eq. (17) part by cm."""
    Y = rng.uniform(-0.75, 0.75, (8, 2))
    cases = []
    for k in range(3):
        x0, y0, th = rng.uniform([-0.1, -0.1, -0.25], [0.1, 0.1, 0.25])
        X = (Y - [x0, y0]) @ rotation(th) + rng.normal(0, 0.02, Y.shape)  # R(θ)ᵀ (Y - t)
        if k == 2:
            X[rng.integers(8)] += [0.30, 0.0]
        a, ls = align_mean_distance(X, Y), align_least_squares(X, Y)
        cases.append({"X": X, "Y": Y.copy(), "want": np.array([a.x0, a.y0, a.theta0])})
        cases[-1]["least_squares"] = np.array([ls.x0, ls.y0, ls.theta0])
        cases[-1]["mean_error"] = a.mean_error
    return cases


def _inverse(params: Array) -> Array:
    """The transform that undoes world = R(θ0) X + (x0, y0)."""
    theta = -params[2]
    return np.array([*(-(rotation(theta) @ params[:2])), theta])


def _judge_alignment(call: Callable, case: dict) -> None:
    X, Y, params = case["X"], case["Y"], case["want"]
    got = as_array(call(("X", X), ("Y", Y)), (3,), "your (x0, y0, θ0)")
    got[2] = wrap_angle(float(got[2]))
    moved = X @ rotation(got[2]).T + got[:2]
    mine = float(np.mean(np.hypot(*(moved - Y).T)))
    # eq. (17)'s minimum is flat (a mean of distances): a transform whose mean distance is within
    # 0.1 µm of it is right (a generic optimiser, Powell's, stops ~1e-8 above it; least squares
    # leaves at least 2e-6 more on 600 drawn maps)
    if close(got, params, atol=1e-6) or mine <= case["mean_error"] + 1e-7:
        return
    if np.allclose(got, _inverse(params), rtol=0, atol=1e-4):
        raise Wrong(
            "your transform lays the true map onto the estimate (Y onto X); eq. (17) lays the "
            "estimate onto the true map: world = R(θ0) X + (x0, y0)."
        )
    if abs(got[2] + params[2]) < 1e-4 and abs(params[2]) > 1e-3:
        raise Wrong("θ0 has the wrong sign: the true map is R(θ0) X + (x0, y0).")
    if np.allclose(got, case["least_squares"], rtol=0, atol=1e-5):
        raise Wrong(
            "you minimised the squared distances (least squares), not eq. (17)'s mean "
            "distance: they part when one tag is far off."
        )
    raise Wrong("your transform leaves a larger mean distance than eq. (17)'s minimum.")


ALIGNMENT_EXERCISE = Exercise(
    "9", "align_map", _maps, _judge_alignment, allowed=lambda: (rotation, wrap_angle)
)  # its sandbox keeps the geometry only: every module of the alignment is left out


def check_alignment(align_map: Callable[[Array, Array], object]) -> bool:
    """Exercise 9: `align_map(X (N, 2), Y (N, 2)) -> (x0, y0, θ0)`, the transform with
    Y ≈ R(θ0) X + (x0, y0) that minimises eq. (17), the mean distance, to 1e-6 m and rad."""
    return attempt(ALIGNMENT_EXERCISE, align_map)


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
