"""The tuning panel says what the command line says: the diagnosis under the table, red when the
filter disagrees with its data; its "fit R and Q" button finds the noise itself (issue 26)."""

from __future__ import annotations

import pytest
from matplotlib.figure import Figure

from ekfslam.logs.runlog import read_run
from ekfslam.ui.tuning import RUNS_DIR, Tuner
from ekfslam.ui.widgets import TuningPanel


@pytest.fixture
def panel() -> TuningPanel:
    runs = {"square-2laps": lambda: read_run(RUNS_DIR / "square-2laps")}
    tuner = Tuner(runs, Figure(figsize=(4, 3)), blit=False)
    tuner.apply()
    return TuningPanel(tuner)


def test_an_ok_replay_is_green_and_a_lost_one_red_with_what_to_try(panel) -> None:
    assert 'class="ekfslam-diagnosis" style="color:#070' in panel.status.value
    assert "diagnosis: ok" in panel.status.value
    assert panel.tuner.state.text.endswith("; diagnosis: ok")
    panel.apply(sigma_range=0.001, sigma_bearing=0.001)
    assert 'style="color:#b00' in panel.status.value
    assert "diagnosis: lost:" in panel.status.value
    assert "try &#x27;fit R and Q&#x27;" in panel.status.value  # escaped quotes
    assert panel.tuner.state.text.endswith("; diagnosis: lost")


@pytest.mark.slow
def test_the_fit_button_brings_a_lost_setting_back_and_the_sliders_follow(panel) -> None:
    panel.apply(sigma_range=0.001, sigma_bearing=0.001)
    panel.fit.click()
    fitted = panel.tuner.last_fit
    assert fitted is not None and fitted.diagnosis.verdict == "ok"
    assert panel.tuner.state.summary.diagnosis.verdict == "ok"
    assert panel.sliders["sigma_range"].value == pytest.approx(fitted.noise.sigma_range, rel=1e-9)
    assert 0.01 < fitted.noise.sigma_range < 0.04  # the simulated camera's 0.02
    assert "diagnosis: ok" in panel.status.value
