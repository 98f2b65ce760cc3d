"""The lab's grading key: every exercise's cases drawn at release time, and `grade`, which the
hidden test of each exercise calls while the lab is graded.

`write_key` draws each exercise's cases (`EXERCISES`) from a seed chosen at release and stores
them with the values a right answer gives, computed then by the package: so the graded cases are
inputs the students never saw, and the expected values cannot be changed by anything a
submission does to the package while it runs. Exercise 8's case is a run simulated at release
(the octagon or the square, one lap, a camera rate drawn between 6 and 9 Hz so that most
detections fall between two control times). The key lives in the instructor's course folder,
never in the students' copy.

`grade(exercise, fn)` runs the exercise's judge (`ekfslam.teaching.verdicts`) on the key's cases
(the key named by ``$EKFSLAM_LAB_KEY``), prints one line and returns the score, 0 to 1: the share
of cases right, 0 when the function calls the package's own implementation or ignores its
inputs. nbgrader reads that number as the cell's partial credit.
"""

from __future__ import annotations

import functools
import os
import pickle
import secrets
from pathlib import Path

import numpy as np

from ekfslam.analysis.lab_checks import ALIGNMENT_EXERCISE, REPLAY_EXERCISE, replay_case
from ekfslam.errors import InputError
from ekfslam.sim.simulation import SimulationConfig, simulate
from ekfslam.teaching import exercises as ex
from ekfslam.teaching import map_exercises as mx
from ekfslam.teaching.verdicts import Exercise, Verdict, run_exercise

#: Every exercise of the lab, by its number (the CSV's columns, in this order).
EXERCISES: dict[str, Exercise] = {
    e.number: e
    for e in (
        ex.TWIST_EXERCISE,
        ex.TWIST_COVARIANCE_EXERCISE,
        ex.MOTION_JACOBIANS_EXERCISE,
        ex.MOTION_NOISE_EXERCISE,
        ex.PREDICT_EXERCISE,
        mx.OBSERVATION_MODEL_EXERCISE,
        mx.PREDICTED_OBSERVATION_EXERCISE,
        mx.NEW_LANDMARK_EXERCISE,
        mx.JOSEPH_EXERCISE,
        mx.UPDATE_EXERCISE,
        mx.NIS_GATE_EXERCISE,
        REPLAY_EXERCISE,
        ALIGNMENT_EXERCISE,
    )
}
KEY_ENV = "EKFSLAM_LAB_KEY"
KEY_VERSION = 1


def hidden_run(rng: np.random.Generator):
    """Exercise 8's graded run: one lap of the octagon or the square from a random start error,
    its camera at a rate whose frames mostly fall between the 20 Hz control times."""
    config = SimulationConfig(
        trajectory=str(rng.choice(["octagon", "square"])),
        laps=1,
        seed=int(rng.integers(1_000_000)),
        start_error=tuple(rng.uniform([-0.05, -0.05, -0.15], [0.05, 0.05, 0.15])),
        camera_hz=float(rng.choice([6.0, 7.0, 8.0, 9.0])),
    )
    return simulate(config)


def hidden_cases(seed: int) -> dict[str, list[dict]]:
    """Every exercise's graded cases, drawn from `seed` (each exercise its own stream)."""
    streams = np.random.SeedSequence(seed).spawn(len(EXERCISES))
    cases = {}
    for (number, exercise), stream in zip(EXERCISES.items(), streams, strict=True):
        rng = np.random.default_rng(stream)
        if exercise is REPLAY_EXERCISE:
            cases[number] = [replay_case(hidden_run(rng))]
        else:
            cases[number] = exercise.make_cases(rng)
    return cases


def write_key(path: Path, seed: int | None = None) -> int:
    """Draw the graded cases (from `seed`, else a fresh random one) and store them at `path`;
    returns the seed."""
    seed = secrets.randbits(63) if seed is None else seed
    key = {"version": KEY_VERSION, "seed": seed, "cases": hidden_cases(seed)}
    path.write_bytes(pickle.dumps(key, protocol=pickle.HIGHEST_PROTOCOL))
    return seed


@functools.cache
def read_key(path: str) -> dict[str, list[dict]]:
    """The graded cases stored at `path` by `write_key` (the instructor's own file)."""
    try:
        key = pickle.loads(Path(path).read_bytes())
    except (OSError, pickle.UnpicklingError, EOFError) as error:
        raise InputError(path, None, f"not a lab key ({error})") from None
    if not isinstance(key, dict) or key.get("version") != KEY_VERSION:
        raise InputError(path, None, "not a lab key of this ekfslam (run `lab release` again)")
    return key["cases"]


def grade_exercise(number: str, fn: object, key: str | os.PathLike) -> Verdict:
    """Exercise `number`'s verdict for `fn` on the graded cases in `key`."""
    return run_exercise(EXERCISES[number], fn, read_key(str(key))[number])


def grade(number: str, fn: object) -> float | None:
    """The hidden test of exercise `number`: `fn` on the graded cases of ``$EKFSLAM_LAB_KEY``;
    prints the verdict and returns the score, 0 to 1. Outside grading (no key: the instructor
    runs the source notebook) it does nothing and returns None."""
    key = os.environ.get(KEY_ENV)
    if not key:
        return None
    verdict = grade_exercise(number, fn, key)
    print(f"Graded on {verdict.total} cases you have not seen: {verdict.line}")
    return round(verdict.score, 4)
