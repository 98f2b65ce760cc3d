"""The lab: the student notebooks are current, every solution passes its check, every stub is
"not done yet", and each check names a typical wrong answer (without the right value)."""

from __future__ import annotations

import functools
import json
import re

import numpy as np
import pytest

from ekfslam import EKFSLAM
from ekfslam.analysis import lab_checks as lc
from ekfslam.core.steps import new_landmark_step, predict_step
from ekfslam.errors import InputError
from ekfslam.logs.runlog import read_run
from ekfslam.teaching import exercises as ex
from ekfslam.teaching import make_lab
from ekfslam.teaching import map_exercises as mx
from ekfslam.teaching.reference import LiteralEKFSLAM

# exercise -> (the function its cell defines, its check)
LAB = {
    "1a": ("twist_from_wheels", ex.check_twist),
    "1b": ("twist_covariance", ex.check_twist_covariance),
    "2a": ("derive_motion_jacobians", ex.check_motion_jacobians),
    "2b": ("motion_noise_R", ex.check_motion_noise),
    "3": ("predict", ex.check_predict),
    "4a": ("derive_observation", mx.check_observation_model),
    "4b": ("predict_z", mx.check_predicted_observation),
    "5": ("add_landmark", mx.check_new_landmark),
    "6a": ("joseph", mx.check_joseph),
    "6b": ("update", mx.check_update),
    "7": ("nis_gate", mx.check_nis_gate),
    "8": ("replay_loop", lc.check_replay),
    "9": ("align_map", lc.check_alignment),
}


@functools.cache
def octagon():
    """The seed's octagon run, whose Table 1 row exercise 8 reproduces."""
    return read_run(make_lab.NOTEBOOKS.parent / "data" / "runs" / "octagon-2laps")


def exercise_cells() -> dict[str, str]:
    """exercise -> the source of the code cell that holds its solution, from every source."""
    cells = {}
    for path in sorted(make_lab.SOLUTIONS.glob("*.ipynb")):
        for cell in json.loads(path.read_text(encoding="utf-8"))["cells"]:
            text = "".join(cell["source"])
            for n in re.findall(r"# BEGIN SOLUTION exercise (\w+)", text):
                cells[n] = text
    return cells


def defined(source: str, name: str):
    namespace = {"np": np}
    exec(compile(source, f"<exercise cell {name}>", "exec"), namespace)
    return namespace[name]


def test_the_student_notebooks_are_current() -> None:
    assert make_lab.stale() == [], "run python -m ekfslam.teaching.make_lab"
    assert sorted(exercise_cells()) == sorted(LAB)


def student_cells() -> dict[str, str]:
    """exercise -> the source of its cell in the students' copy (the stub in place)."""
    cells = {}
    for path in sorted(make_lab.SOLUTIONS.glob("*.ipynb")):
        student = make_lab.NOTEBOOKS / path.name
        for cell in json.loads(student.read_text(encoding="utf-8"))["cells"]:
            grade_id = cell["metadata"].get("nbgrader", {}).get("grade_id", "")
            if grade_id.startswith("answer-"):
                for n in grade_id.removeprefix("answer-").split("-"):
                    cells[n] = "".join(cell["source"])
    return cells


@pytest.mark.parametrize("n", sorted(LAB))
def test_every_solution_passes_and_every_stub_is_not_done_yet(n: str, capsys) -> None:
    name, check = LAB[n]
    source = exercise_cells()[n]
    assert check(defined(source, name)) is True
    assert f"Exercise {n}: right on every test case" in capsys.readouterr().out
    stub = student_cells()[n]
    assert make_lab.STUB in stub and "SOLUTION" not in stub
    assert check(defined(stub, name)) is False
    assert f"Exercise {n}: not done yet" in capsys.readouterr().out


def test_the_students_copy_holds_no_solution_and_no_hidden_test() -> None:
    for path in sorted(make_lab.SOLUTIONS.glob("*.ipynb")):
        student = (make_lab.NOTEBOOKS / path.name).read_text(encoding="utf-8")
        source = path.read_text(encoding="utf-8")
        assert "BEGIN SOLUTION" in source and "BEGIN SOLUTION" not in student, path.name
        assert "HIDDEN TESTS" not in student and "lab_key" not in student, path.name
        assert "lab_key" not in student and "grade(" not in student, path.name


def test_no_check_or_docstring_says_where_the_answer_lives() -> None:
    """The checks' docstrings and the notebooks' check cells never name the package's version
    of the exercise as "the answer"."""
    import inspect

    texts = [inspect.getsource(m) for m in (ex, mx, lc)]
    texts += [p.read_text(encoding="utf-8") for p in make_lab.NOTEBOOKS.glob("0*.ipynb")]
    for text in texts:
        assert not re.search(r"answer is `?ekfslam", text), text[:80]


def test_the_jacobians_are_derived_by_sympy_in_the_notebook() -> None:
    assert ".jacobian(" in exercise_cells()["2a"]
    assert ".jacobian(" in exercise_cells()["4a"]


def test_make_lab_check_says_current(capsys) -> None:
    assert make_lab.main(["--check"]) == 0
    assert capsys.readouterr().out == ""


# --- each check names a typical wrong answer ----------------------------------------------------


def verdict(check, fn, capsys) -> str:
    assert check(fn) is False
    return capsys.readouterr().out


def right_twist(w, g):
    r, k = g.wheel_radius, g.lx + g.ly
    w1, w2, w3, w4 = w
    return r / 4 * np.array([w1 + w2 + w3 + w4, -w1 + w2 + w3 - w4, (-w1 + w2 - w3 + w4) / k])


def test_predict_step_is_the_filters_and_the_literal_prediction() -> None:
    pose, P0 = [0.1, -0.2, 3.1], np.diag([1e-4, 2e-4, 1e-3])
    Q = np.diag([0.03**2, 0.03**2])
    fast, literal = EKFSLAM(pose, P0), LiteralEKFSLAM(pose, P0)
    for f in (fast, literal):
        f.update(0, [1.0, 0.2], Q)
        f.update(1, [0.8, -0.5], Q)
    mu, Sigma = fast.mu.copy(), fast.Sigma.copy()
    u, R = np.array([0.05, 0.01, 0.2]), np.diag([1e-5, 2e-5, 4e-5])
    fast.predict(u, R)
    literal.predict(u, R)
    mu2, Sigma2 = predict_step(mu, Sigma, u, R)
    assert -np.pi <= mu2[2] < 0  # 3.1 + 0.2 wrapped
    np.testing.assert_allclose(mu2, fast.mu, atol=1e-12)
    np.testing.assert_allclose(Sigma2, fast.Sigma, atol=1e-12)
    np.testing.assert_allclose(Sigma2, literal.Sigma, atol=1e-12)


def test_make_lab_refuses_a_broken_source_in_one_line(monkeypatch, tmp_path, capsys) -> None:
    (tmp_path / "solutions").mkdir()
    (tmp_path / "solutions" / "05-y.ipynb").write_text("{not json")
    monkeypatch.setattr(make_lab, "NOTEBOOKS", tmp_path)
    monkeypatch.setattr(make_lab, "SOLUTIONS", tmp_path / "solutions")
    assert make_lab.main([]) == 2
    err = capsys.readouterr().err
    assert err.startswith("make_lab: ") and "05-y.ipynb: not a readable notebook" in err
    assert err.count("\n") == 1
    assert not (tmp_path / "05-y.ipynb").exists()  # nothing written half-way


def test_new_landmark_step_is_the_filters_initialisation() -> None:
    Q = np.diag([9e-4, 4e-3])
    fast = EKFSLAM([0.1, -0.2, 0.4], np.diag([1e-4, 2e-4, 1e-3]))
    fast.update(0, [1.0, 0.2], Q)
    fast.predict([0.05, 0.01, 0.1], np.diag([1e-5, 1e-5, 4e-5]))
    mu, Sigma = fast.mu.copy(), fast.Sigma.copy()
    fast.update(1, [0.8, -0.5], Q)  # init="inverse": placed, not corrected
    mu2, Sigma2 = new_landmark_step(mu, Sigma, [0.8, -0.5], Q)
    np.testing.assert_allclose(mu2, fast.mu, atol=1e-12)
    np.testing.assert_allclose(Sigma2, fast.Sigma, atol=1e-12)


def _short_form(Sigma, K, H, Q):  # the seed's eq. (16)
    return (np.eye(len(Sigma)) - K @ H) @ Sigma


def test_check_joseph_tells_the_seeds_short_form_the_missing_KQK_and_the_transposes(capsys) -> None:
    def no_KQK(Sigma, K, H, Q):
        I_KH = np.eye(len(Sigma)) - K @ H
        return I_KH @ Sigma @ I_KH.T

    def transposed(Sigma, K, H, Q):
        I_KH = np.eye(len(Sigma)) - K @ H
        return I_KH.T @ Sigma @ I_KH + K @ Q @ K.T

    check = mx.check_joseph
    out = verdict(check, _short_form, capsys)
    assert "that is the seed's (I - KH)Σ, which is right only for the optimal gain" in out
    assert "with 1.2 K" in out
    assert "K Q Kᵀ is missing" in verdict(check, no_KQK, capsys)
    assert "transposes are on the wrong side" in verdict(check, transposed, capsys)


def _exercise_6(*edits: tuple[str, str]) -> dict:
    """The names exercise 6's cell defines, with each (old, new) text replaced first."""
    source = exercise_cells()["6b"]
    for old, new in edits:
        assert source.count(old) == 1, old
        source = source.replace(old, new)
    namespace = {"np": np}
    exec(compile(source, "<exercise cell 6>", "exec"), namespace)
    return namespace


JOSEPH = "return I_KH @ Sigma @ I_KH.T + K @ Q @ K.T"
SHORT = "return I_KH @ Sigma"


def test_the_short_form_passes_the_update_but_not_joseph(capsys) -> None:
    cell = _exercise_6((JOSEPH, SHORT))
    assert mx.check_update(cell["update"]) is True  # the optimal gain: both forms agree
    assert mx.check_joseph(cell["joseph"]) is False  # other gains: 6a tells them apart


def test_check_update_says_when_the_update_does_not_use_joseph_or_joseph_is_a_stub(capsys) -> None:
    inline = "return mu, (np.eye(d) - K @ H) @ Sigma"
    cell = _exercise_6(("return mu, joseph(Sigma, K, H, Q)  # exercise 6a", inline))
    out = verdict(mx.check_update, cell["update"], capsys)
    assert "does not call your joseph(Sigma, K, H, Q) of exercise 6a" in out
    cell = _exercise_6(("I_KH = np.eye(len(Sigma)) - K @ H", "raise NotImplementedError"))
    assert "exercise 6a is not done yet" in verdict(mx.check_update, cell["update"], capsys)


def test_an_unclosed_solution_region_is_refused_naming_the_cell() -> None:
    nb = {
        "cells": [
            {
                "cell_type": "code",
                "metadata": {"nbgrader": {"solution": True}},
                "source": ["def f():\n", "    # BEGIN SOLUTION\n", "    return 1\n"],
            }
        ]
    }
    with pytest.raises(InputError, match="cell 0: a region opened and never closed"):
        make_lab.student_notebook(nb, "x.ipynb")


def test_the_students_copy_keeps_no_solution_and_no_hidden_test() -> None:
    src = {
        "cells": [
            {
                "cell_type": "code",
                "metadata": {"nbgrader": {"solution": True, "grade_id": "a"}},
                "outputs": [1],
                "execution_count": 3,
                "source": ["x = None\n", "    # BEGIN SOLUTION\n", "x = 42\n", "# END SOLUTION"],
            },
            {
                "cell_type": "code",
                "metadata": {"nbgrader": {"grade": True, "locked": True}},
                "source": [
                    "check(x)\n",
                    "### BEGIN HIDDEN TESTS\n",
                    "secret()\n",
                    "### END HIDDEN TESTS",
                ],
            },
        ]
    }
    out = make_lab.student_notebook(src)
    answer, check = out["cells"]
    assert answer["source"] == ["x = None\n", f"    {make_lab.STUB}"]
    assert answer["outputs"] == [] and answer["execution_count"] is None
    assert check["source"] == ["check(x)"] and check["metadata"]["editable"] is False
    assert src["cells"][0]["source"][2] == "x = 42\n"  # the source is left as it was
