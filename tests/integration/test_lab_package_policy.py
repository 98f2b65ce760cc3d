"""What of the package a graded sandbox holds (`ekfslam.cli.lab_sandbox.package_for`), tried as a
student's cell would try it: every way to the package's answer to the exercise raises
`LabForbidden`, and what the exercise allows (its notebook's helpers) runs.

Each exercise's package is built as `lab grade` builds it, and the probes run in a fresh
interpreter that sees that package only (``python -I`` with the built folder first on its path),
as the sandbox's notebook does. A probe is a cell's code: its outcome is "forbidden" when it
raised `LabForbidden`, "ran" when it returned, and the exception's name when the function ran
and failed on the probe's inputs (it was reachable: a cheat could have called it right).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from ekfslam.analysis.lab_key import EXERCISES
from ekfslam.cli.lab_sandbox import package_for

GEOMETRY = "from ekfslam.core.kinematics import MecanumGeometry\ng = MecanumGeometry()\n"
RUN = "from ekfslam.logs.runlog import RunLog\n"

#: per exercise, cells that reach the package's answer (or what does its work) by some name
ANSWERS: dict[str, list[str]] = {
    "1a": [
        GEOMETRY + "from ekfslam.core.kinematics import wheels_to_twist\n"
        "wheels_to_twist(np.ones(4), g)",
        GEOMETRY + "g.wheels_to_twist_matrix @ np.ones(4)",
        GEOMETRY + "import ekfslam\nekfslam.wheels_to_twist(np.ones(4), g)",
        GEOMETRY + "np.linalg.pinv(g.twist_to_wheels_matrix)",
        "from ekfslam.core import kinematics\nkinematics.wheels_to_twist(np.ones(4), "
        "kinematics.MecanumGeometry())",
    ],
    "1b": [
        GEOMETRY + "from ekfslam.core.kinematics import wheel_noise_to_twist_covariance\n"
        "wheel_noise_to_twist_covariance(np.ones(4), g)",
        GEOMETRY + "import ekfslam.core.kinematics as k\nk.wheels_to_twist(np.ones(4), g)",
    ],
    "2a": [
        "from ekfslam.teaching import derivations\nderivations.motion_model()",
        "from ekfslam.core.models import motion_jacobian\nmotion_jacobian(np.zeros(3), np.ones(3))",
        "from ekfslam.core.models import motion_control_jacobian\n"
        "motion_control_jacobian(np.zeros(3))",
    ],
    "2b": [
        "from ekfslam.core.models import motion_noise\nmotion_noise(np.zeros(3), np.eye(3))",
        "from ekfslam.core.models import motion_control_jacobian\n"
        "motion_control_jacobian(np.zeros(3))",
        "from ekfslam.core.noise import default_noise\ndefault_noise(None)",
    ],
    "3": [
        "from ekfslam.core.steps import predict_step\n"
        "predict_step(np.zeros(3), np.eye(3), np.ones(3), np.eye(3))",
        "import ekfslam\nekfslam.EKFSLAM(np.zeros(3)).predict(np.ones(3))",
        "from ekfslam.teaching.reference import LiteralEKFSLAM\nLiteralEKFSLAM(np.zeros(3))",
        "from ekfslam.core.filter import steps\nsteps.predict",
    ],
    "4a": [
        "from ekfslam.teaching import derivations\nderivations.observation_model()",
        "from ekfslam.core.models import observation_jacobians\n"
        "observation_jacobians(np.zeros(3), np.ones(2))",
        "from ekfslam.teaching import derivations\nderivations.robot_observation_model()",
        "from ekfslam.core.models import robot_observation_jacobians\n"
        "robot_observation_jacobians(np.zeros(3), np.ones(3))",
    ],
    "4b": [
        "from ekfslam.core.models import observation\nobservation(np.zeros(3), np.ones(2))",
        "from ekfslam.core import models\nmodels.observation(np.zeros(3), np.ones(2))",
        "from ekfslam.core import models\nmodels.robot_observation(np.zeros(3), np.ones(3))",
        "from ekfslam.core import models\nmodels.ROBOT_RANGE_BEARING.h(np.zeros(3), np.ones(3))",
        "from ekfslam.core.steps import update_steps\nupdate_steps",
    ],
    "5": [
        "from ekfslam.core.steps import new_landmark_step\n"
        "new_landmark_step(np.zeros(3), np.eye(3), np.ones(2), np.eye(2))",
        "import ekfslam\nekfslam.EKFSLAM(np.zeros(3)).update(np.ones(2), 0)",
    ],
    "6a": [
        "from ekfslam.core.steps import update_steps\n"
        "update_steps(np.zeros(5), np.eye(5), 0, np.ones(2), np.eye(2))",
        "from ekfslam.core.filter import steps\nsteps.correct",
    ],
    "6b": [
        "from ekfslam.core.steps import update_steps\n"
        "update_steps(np.zeros(5), np.eye(5), 0, np.ones(2), np.eye(2))",
        "import ekfslam\nekfslam.EKFSLAM(np.zeros(3)).update(np.ones(2), 0)",
        "from ekfslam.teaching import reference\nreference.LiteralEKFSLAM",
    ],
    "7": [
        "from ekfslam.core.filter.config import chi2_2dof_quantile\nchi2_2dof_quantile(0.99)",
        "from ekfslam.core.steps import update_steps\nupdate_steps",
        "from ekfslam.core import association\nassociation.mahalanobis",
    ],
    "8": [
        "import ekfslam\nekfslam.replay(None, None)",
        "from ekfslam.pipeline import replay\nreplay(None, None)",
        "from ekfslam.analysis.replay_mistakes import mistaken_loop\nmistaken_loop(None)",
        "from ekfslam.core.filter.ekf import EKFSLAM\nEKFSLAM.feed(None, None, None)",
        "from ekfslam.core.filter.steps import feed\nfeed(None, 0, None, None, None, None)",
    ],
    "9": [
        "import ekfslam\nekfslam.align({}, {})",
        "from ekfslam.analysis.alignment import align\nalign({}, {})",
        "from ekfslam.analysis.alignment import align_mean_distance\n"
        "align_mean_distance(np.ones((3, 2)), np.ones((3, 2)))",
        "from ekfslam.analysis import _alignment_solver\n_alignment_solver.solve",
    ],
}

#: per exercise, the helpers its notebook and its check allow: each must run
ALLOWED: dict[str, list[str]] = {
    "1a": [GEOMETRY + "g.wheel_radius + g.lx + g.ly"],
    "1b": [GEOMETRY + "g.wheels_to_twist_matrix @ np.ones(4)"],
    "2a": ["from ekfslam.teaching.symbols import x, y, theta\nx + y + theta"],
    "2b": ["from ekfslam.geometry import rotation\nrotation(0.3)"],
    "3": [
        "from ekfslam.core.models import motion, motion_jacobian, wrap_angle\n"
        "motion(np.zeros(3), np.ones(3)) @ motion_jacobian(np.zeros(3), np.ones(3))"
    ],
    "4b": ["from ekfslam.geometry import wrap_angle\nwrap_angle(4.0)"],
    "5": [
        "from ekfslam.core.models import inverse_observation, inverse_observation_jacobians\n"
        "inverse_observation(np.zeros(3), np.array([1.0, 0.2]))\n"
        "inverse_observation_jacobians(np.zeros(3), np.array([1.0, 0.2]))"
    ],
    "6b": [
        "from ekfslam.core.models import observation, observation_jacobians\n"
        "observation(np.zeros(3), np.ones(2))\nobservation_jacobians(np.zeros(3), np.ones(2))"
    ],
    "7": ["from ekfslam.geometry import wrap_angle\nwrap_angle(-4.0)"],
    "8": [
        RUN + "from ekfslam.analysis.watched_filter import WatchedEKF\n"
        "from ekfslam.core.noise import NoiseConfig\nNoiseConfig()",
        "from ekfslam.core import models, kinematics\nmodels.motion(np.zeros(3), np.ones(3))",
    ],
    "9": ["from ekfslam.geometry import rotation, wrap_angle\nrotation(wrap_angle(7.0))"],
}

PROBE = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
import numpy as np
outcomes = []
for cell in json.loads(sys.argv[2]):
    names = {"np": np}
    try:
        *body, last = cell.splitlines()
        exec("\n".join(body), names)
        value = eval(last, names)
        if type(value).__name__ == "Forbidden":  # a stand-in reached but not called
            value()
        outcomes.append("ran")
    except BaseException as error:
        name = type(error).__name__
        outcomes.append("forbidden" if name == "LabForbidden" else name)
print(json.dumps(outcomes))
"""


def probe(exercise: str, cells: list[str], root: Path) -> list[str]:
    package = package_for(EXERCISES[exercise], root)
    done = subprocess.run(
        [sys.executable, "-I", "-c", PROBE, str(package.parent), json.dumps(cells)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=root,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_every_exercise_has_probes() -> None:
    assert set(ANSWERS) == set(EXERCISES)


@pytest.mark.parametrize("exercise", sorted(EXERCISES))
def test_the_packages_answer_is_forbidden_and_the_helpers_run(exercise, tmp_path) -> None:
    cells = ANSWERS[exercise] + ALLOWED.get(exercise, [])
    outcomes = probe(exercise, cells, tmp_path)
    answers, allowed = outcomes[: len(ANSWERS[exercise])], outcomes[len(ANSWERS[exercise]) :]
    reached = [c for c, o in zip(ANSWERS[exercise], answers, strict=True) if o != "forbidden"]
    assert not reached, f"exercise {exercise}: reachable in its sandbox: {reached} ({answers})"
    broken = [c for c, o in zip(ALLOWED.get(exercise, []), allowed, strict=True) if o != "ran"]
    assert not broken, f"exercise {exercise}: its helpers fail: {broken} ({allowed})"


def test_a_probe_tells_a_reachable_function_from_a_forbidden_one(tmp_path) -> None:
    """The probe's own check: in exercise 9's package the kinematics are left out, in 1a's they
    are kept with the answer poisoned; a plain numpy call runs in both."""
    cell = GEOMETRY + "g.wheel_radius"
    assert probe("9", [cell, "np.ones(2).sum()"], tmp_path / "9") == ["forbidden", "ran"]
    assert probe("1a", [cell, "np.ones(2).sum()"], tmp_path / "1a") == ["ran", "ran"]
