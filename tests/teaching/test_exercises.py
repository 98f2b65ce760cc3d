"""Tests of ekfslam.teaching.exercises: the verdicts on an exercise's answer."""

from __future__ import annotations

from ekfslam.teaching.exercises import check_answer


def test_check_answer(capsys) -> None:
    assert check_answer(None, 1.0) is False
    assert "Not answered yet" in capsys.readouterr().out
    assert check_answer([1.0, 2.0000001], [1.0, 2.0]) is True
    assert "Right" in capsys.readouterr().out
    assert check_answer([1.0, 2.1], [1.0, 2.0]) is False
    assert "off by up to 0.1" in capsys.readouterr().out
    assert check_answer([1.0], [1.0, 2.0]) is False
    assert "shape" in capsys.readouterr().out
    assert check_answer("seven", 7.0) is False
    assert "not a number" in capsys.readouterr().out
