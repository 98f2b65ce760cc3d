"""Exercise 8's check names the typical wrong replay loop: each case below is a student's loop
(the solution's, with one mistake written in) and the check's verdict must name that mistake."""

from __future__ import annotations

import numpy as np
import pytest

from ekfslam import EKFSLAM
from ekfslam.analysis import replay_mistakes as rm
from ekfslam.core.noise import default_config, default_noise
from ekfslam.pipeline import replay
from tests.teaching.test_lab import LAB, defined, exercise_cells, octagon
from tests.teaching.test_lab_late import verdict, whole_intervals

RIGHT = exercise_cells()["8"]


def student_loop(*edits: tuple[str, str]):
    """The solution's replay_loop with each (old, new) text replaced: a student's wrong loop."""
    source = RIGHT
    for old, new in edits:
        assert source.count(old) == 1, old
        source = source.replace(old, new)
    return defined(source, "replay_loop")


PREDICT = "ekf.predict(twist[row] * dt, models.motion_noise(ekf.mu[:3], M * dt), end)"
SIGHT = "ekf.update(int(det.tag_id[k]), (det.range[k], det.bearing[k]), Q, det.t[k])"
WRONG = {
    "unscaled": [(PREDICT, PREDICT.replace("M * dt", "M"))],
    # the detections up to the piece's end applied before predicting it
    "early": [("det.t[k] <= start:", "det.t[k] <= end:")],
    "twice": [
        ("    def sight(k):\n", "    met = set()\n\n    def sight(k):\n"),
        (
            SIGHT,
            SIGHT + "\n        if det.tag_id[k] not in met:  # place, then correct (as eq. 3)\n"
            "            met.add(det.tag_id[k])\n            " + SIGHT,
        ),
    ],
    "stops": [("pairwise(times):", "pairwise(times[times <= det.t[-1]]):")],
}
#: a phrase of each verdict (none gives the loop's code away)
SAYS = {
    "whole": "predicts each control interval whole",
    "early": "applies each detection before the pose is predicted up to its time",
    "unscaled": "builds each piece's R from M itself",
    "twice": "feeds each tag's first sighting twice",
    "stops": "stops at the last detection",
}


@pytest.mark.parametrize("mistake", sorted(SAYS))
def test_check_replay_names_each_typical_mistake(mistake, capsys) -> None:
    loop = whole_intervals if mistake == "whole" else student_loop(*WRONG[mistake])
    out = verdict(LAB["8"][1], loop, capsys)
    assert "your numbers are those of a loop that " + SAYS[mistake] in out, out
    others = [p for m, p in SAYS.items() if m != mistake]
    assert not any(p in out for p in others)
    assert "pairwise" not in out and "searchsorted" not in out


@pytest.mark.parametrize("call", ["predict", "update"])
def test_check_replay_names_R_and_Q_swapped(call, capsys) -> None:
    if call == "predict":
        loop = student_loop((PREDICT, "ekf.predict(twist[row] * dt, Q, end)"))
    else:
        R = "models.motion_noise(ekf.mu[:3], M * 0.05)"
        loop = student_loop((SIGHT, SIGHT.replace(", Q, det.t[k])", f", {R}, det.t[k])")))
    out = verdict(LAB["8"][1], loop, capsys)
    shape = "2x2" if call == "predict" else "3x3"
    assert f"ekf.{call} got a {shape} noise matrix" in out and "filterpy" in out, out


def test_the_mistaken_loops_differ_from_the_replay_and_none_is_the_right_one() -> None:
    run, noise = octagon(), default_noise(octagon())
    ekf = EKFSLAM(run.meta.nominal_start, None, default_config(run))
    rm.mistaken_loop(run, ekf, noise, None)
    want = replay(run)
    assert np.abs(ekf.mu - want.mu).max() < 1e-9 and ekf.counts == want.counts
    assert rm.diagnose(run, noise, want.mu, want.counts.predictions) is None
    for mistake in rm.MISTAKES:
        wrong = EKFSLAM(run.meta.nominal_start, None, default_config(run))
        rm.mistaken_loop(run, wrong, noise, mistake)
        same = wrong.mu.shape == want.mu.shape and np.abs(wrong.mu - want.mu).max() < 1e-9
        assert not (same and wrong.counts.predictions == want.counts.predictions), mistake


def test_an_unknown_mistake_is_refused() -> None:
    run = octagon()
    with pytest.raises(ValueError, match="unknown mistake 'late'"):
        rm.mistaken_loop(run, EKFSLAM(run.meta.nominal_start), default_noise(run), "late")
