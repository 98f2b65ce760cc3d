"""The lab's grading key: every exercise's cases drawn at release time, and `grade`, which the
hidden test of each exercise calls while the lab is graded.

`write_key` draws each exercise's cases (`EXERCISES`) from a seed chosen at release and stores
them with the values a right answer gives, computed then by the package: so the graded cases are
inputs the students never saw, and the expected values cannot be changed by anything a
submission does to the package while it runs. Exercise 8's case is a run simulated at release
(the octagon or the square, one lap, a camera rate drawn between 6 and 9 Hz so that most
detections fall between two control times). The key lives in the instructor's course folder,
never in the students' copy.

The key also holds each prediction's outcome (`prediction_outcomes`): the solutions' own
predictions, which the solution notebooks' experiments confirm when they run.

Only the grader reads the key (``python -m ekfslam lab grade``, `ekfslam.cli.lab_worker`): it
runs each exercise's judge on the key's cases, in its own process, calling the student's function
in a sandbox; nothing of the key enters a student's process. `grade` is what an older course's
hidden test cells call: it does nothing and returns None.
"""

from __future__ import annotations

import ast
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
KEY_VERSION = 2


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


def prediction_outcomes(notebooks: list[dict]) -> dict[str, dict[str, str]]:
    """{grade id: {prediction key: outcome}} of the solved notebooks: each prediction check
    (``check_prediction(name, ..., key="02-wheels")`` in a grade cell) and the value its
    solution cell gives `name`."""
    outcomes: dict[str, dict[str, str]] = {}
    for nb in notebooks:
        values: dict[str, str] = {}
        for cell in nb["cells"]:
            meta = cell.get("metadata", {}).get("nbgrader", {})
            if cell.get("cell_type") != "code":
                continue
            try:
                tree = ast.parse("".join(cell.get("source", [])))
            except SyntaxError:  # IPython syntax (a magic): no prediction in it
                continue
            if meta.get("solution"):
                for node in ast.walk(tree):
                    if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant):
                        for target in node.targets:
                            if isinstance(target, ast.Name) and isinstance(node.value.value, str):
                                values[target.id] = node.value.value
            if not meta.get("grade"):
                continue
            for node in ast.walk(tree):
                if not (
                    isinstance(node, ast.Call)
                    and getattr(node.func, "id", "") == "check_prediction"
                ):
                    continue
                key = next((k.value for k in node.keywords if k.arg == "key"), None)
                first = node.args[0] if node.args else None
                if not isinstance(key, ast.Constant) or not isinstance(first, ast.Name):
                    continue
                if first.id not in values:
                    raise ValueError(f"prediction {key.value}: no solved value of {first.id}")
                outcomes.setdefault(meta["grade_id"], {})[key.value] = values[first.id]
    return outcomes


def write_key(path: Path, seed: int | None = None, solved: list[dict] | None = None) -> int:
    """Draw the graded cases (from `seed`, else a fresh random one) and store them at `path`,
    with the predictions' outcomes of the solved notebooks `solved`; returns the seed."""
    seed = secrets.randbits(63) if seed is None else seed
    key = {
        "version": KEY_VERSION,
        "seed": seed,
        "cases": hidden_cases(seed),
        "predictions": prediction_outcomes(solved or []),
    }
    path.write_bytes(pickle.dumps(key, protocol=pickle.HIGHEST_PROTOCOL))
    return seed


def read_key(path: str | os.PathLike) -> dict:
    """The key stored at `path` by `write_key` (the instructor's own file): its "cases",
    "predictions" and "seed"."""
    try:
        key = pickle.loads(Path(path).read_bytes())  # the instructor's own file, never a student's
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError) as error:
        raise InputError(str(path), None, f"not a lab key ({error})") from None
    if not isinstance(key, dict) or key.get("version") != KEY_VERSION:
        raise InputError(str(path), None, "not a lab key of this ekfslam (run `lab release` again)")
    return key


def grade_exercise(number: str, fn: object, key: str | os.PathLike) -> Verdict:
    """Exercise `number`'s verdict for `fn` on the graded cases in `key` (in this process: for
    the instructor's own checks; students are graded by ``lab grade``, in sandboxes)."""
    return run_exercise(EXERCISES[number], fn, read_key(key)["cases"][number])


def grade(number: str, fn: object) -> None:
    """What the hidden test cells of a course released before the sandboxed grader call: nothing
    (the grader scores outside the notebook's process now)."""
    return None
