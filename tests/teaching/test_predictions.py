"""Predict-then-test exercises: `check_prediction` compares the student's word with the
experiment's outcome and explains it either way; the notebooks use it where an exercise used to
ask for a number read off a table."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ekfslam.teaching.exercises import check_prediction

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


@pytest.mark.parametrize(
    "name",
    [
        "01-index.ipynb",
        "solutions/02-robot-and-arena.ipynb",
        "solutions/06-full-slam.ipynb",
        "solutions/07-alignment.ipynb",
        "08-live-tuning.ipynb",
        "10-real-robots.ipynb",
    ],
)
def test_the_exercises_that_read_a_number_now_ask_for_a_prediction(name: str) -> None:
    cells = json.loads((NOTEBOOKS / name).read_text(encoding="utf-8"))["cells"]
    code = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
    text = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")
    assert "check_prediction(" in code and "Predict" in text
