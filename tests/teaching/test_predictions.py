"""Predict-then-test exercises: `check_prediction` compares the student's word with the
experiment's outcome and explains it either way; the notebooks use it where an exercise used to
ask for a number read off a table."""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from ekfslam.teaching.exercises import PREDICTIONS, check_prediction, recorded_predictions

CHOICES = ["larger", "smaller"]
WHY = "Σ follows the assumed noise."


def verdict(prediction, capsys, outcome="larger") -> tuple[bool, str]:
    ok = check_prediction(prediction, outcome, CHOICES, WHY)
    return ok, capsys.readouterr().out


def test_a_right_prediction_is_confirmed_and_explained(capsys) -> None:
    assert verdict("larger", capsys) == (True, "Right: larger. Σ follows the assumed noise.\n")


def test_a_wrong_prediction_gets_the_outcome_and_the_explanation(capsys) -> None:
    ok, out = verdict("smaller", capsys)
    assert not ok and out.startswith("Not what happened: you predicted 'smaller'")
    assert "'larger'" in out and WHY in out


def test_no_prediction_yet_names_the_choices_and_gives_nothing_away(capsys) -> None:
    ok, out = verdict(None, capsys)
    assert not ok and out.startswith("Not answered yet") and "'larger' or 'smaller'" in out
    assert WHY not in out


def test_a_word_that_is_not_a_choice_is_refused_without_the_outcome(capsys) -> None:
    ok, out = verdict("bigger", capsys)
    assert not ok and "'bigger' is not one of the choices" in out and WHY not in out


def test_an_outcome_outside_the_choices_is_our_bug() -> None:
    with pytest.raises(ValueError, match="outcome 'same' is not one of"):
        check_prediction("larger", "same", CHOICES, WHY)


NOTEBOOKS = Path(__file__).resolve().parents[2] / "notebooks"
ROOT = NOTEBOOKS.parent


@pytest.mark.parametrize(
    "name",
    [
        "01-index.ipynb",
        "../solutions/02-robot-and-arena.ipynb",
        "../solutions/06-full-slam.ipynb",
        "../solutions/07-alignment.ipynb",
        "08-live-tuning.ipynb",
        "10-real-robots.ipynb",
    ],
)
def test_the_exercises_that_read_a_number_now_ask_for_a_prediction(name: str) -> None:
    cells = json.loads((NOTEBOOKS / name).read_text(encoding="utf-8"))["cells"]
    code = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
    text = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")
    assert "check_prediction(" in code and "Predict" in text


# --- the first prediction is recorded beside the notebook, and is the one that counts ----------


def test_the_first_prediction_is_recorded_and_a_rerun_cannot_change_it(
    tmp_path, monkeypatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)  # Jupyter runs a notebook in its own folder
    assert check_prediction("smaller", "larger", CHOICES, WHY, key="06-sigma") is False
    assert json.loads((tmp_path / PREDICTIONS).read_text()) == {"06-sigma": "smaller"}
    capsys.readouterr()
    # the outcome seen, the cell changed and run again: still the first guess
    assert check_prediction("larger", "larger", CHOICES, WHY, key="06-sigma") is False
    out = capsys.readouterr().out
    assert "Your first prediction, 'smaller', is recorded" in out
    assert "you predicted 'smaller'" in out
    assert json.loads((tmp_path / PREDICTIONS).read_text()) == {"06-sigma": "smaller"}


def test_nothing_is_recorded_before_a_valid_prediction_and_keys_are_apart(
    tmp_path, monkeypatch, capsys
) -> None:
    monkeypatch.chdir(tmp_path)
    check_prediction(None, "larger", CHOICES, WHY, key="a")
    check_prediction("bigger", "larger", CHOICES, WHY, key="a")
    assert not (tmp_path / PREDICTIONS).exists()
    assert check_prediction("larger", "larger", CHOICES, WHY, key="a") is True
    assert check_prediction("smaller", "smaller", CHOICES, WHY, key="b") is True
    assert recorded_predictions(tmp_path) == {"a": "larger", "b": "smaller"}


def test_the_grader_scores_the_handed_in_file_and_nothing_else() -> None:
    from ekfslam.cli.lab_worker import grade_predictions

    outcomes = {"predict-06": {"06-sigma": "larger", "06-error": "smaller"}}
    both = json.dumps({"06-sigma": "larger", "06-error": "smaller"}).encode()
    assert grade_predictions(both, outcomes)["scores"] == {"predict-06": 1.0}
    half = json.dumps({"06-sigma": "larger", "06-error": "larger"}).encode()
    assert grade_predictions(half, outcomes)["scores"] == {"predict-06": 0.5}
    for bad in (None, b"{not json", b"[1, 2]", b'{"06-sigma": ["larger"]}', b"\xff\xfe"):
        graded = grade_predictions(bad, outcomes)
        assert graded["scores"] == {"predict-06": 0.0}, bad
        assert graded["lines"]["predict-06"], bad


@given(st.lists(st.sampled_from(CHOICES), min_size=1, max_size=6))
def test_whatever_is_run_after_it_the_first_answer_stands(answers: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        cwd = os.getcwd()
        os.chdir(tmp)
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                for answer in answers:
                    check_prediction(answer, "larger", CHOICES, WHY, key="k")
            assert recorded_predictions(Path(tmp)) == {"k": answers[0]}
        finally:
            os.chdir(cwd)
