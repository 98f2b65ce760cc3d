"""The notebooks' prose, read as a student reads it: no word of our own issues or targets, and
no claim that the code beside it contradicts."""

from __future__ import annotations

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb")) + sorted(
    (ROOT / "solutions").glob("*.ipynb")
)


def prose(path: Path) -> str:
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    return "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")


def notebook(name: str) -> str:
    return prose(ROOT / "notebooks" / name)


def test_no_notebook_speaks_of_our_issues_or_targets() -> None:
    for path in NOTEBOOKS:
        text = prose(path)
        found = re.findall(r"[^\n]*\b(?:the issue's|our issue|targets?)\b[^\n]*", text, re.I)
        assert not found, f"{path.name}: {found}"


def test_the_motion_lags_the_commands_not_the_other_way_round() -> None:
    """calibrate_commands shifts the commands *later*: the motion comes after them."""
    for path in NOTEBOOKS:
        assert not re.search(r"commands\s+lag", prose(path)), path.name
    assert "motion lags" in notebook("09-trust-the-ellipses.ipynb")


def test_notebook_10_states_no_lag_its_cells_compute() -> None:
    assert not re.search(r"\b\d\.\d+\s*s later", notebook("10-real-robots.ipynb"))


def test_notebook_11_puts_the_robot_where_its_code_does() -> None:
    text = notebook("11-pixels-to-range-bearing.ipynb")
    assert "stands at the arena's centre" not in text and "stands at `pose`" in text


def test_notebook_07_does_not_call_its_translations_the_seeds_size() -> None:
    assert "of the seed's size" not in prose(ROOT / "solutions" / "07-alignment.ipynb")


def test_notebook_03_says_what_sigma_0_of_eq_2_means() -> None:
    text = prose(ROOT / "solutions" / "03-motion-and-prediction.ipynb")
    assert "eq. (2)" in text and "gauge" in text and "rigid transform" in text
    assert "eq. (17)" in text and "eq. (12)" in text  # recovered by 17; landmarks enter by 12


def test_notebooks_09_and_10_state_the_lag_and_the_short_drive_notebook_10_measures(
    mrclam7,
) -> None:
    """Notebook 10's cell fits robot 3's lag and distance scale; both texts quote them."""
    from ekfslam.logs.mrclam.calibration import fit_command_calibration
    from ekfslam.logs.mrclam.load import load_mrclam

    fit = fit_command_calibration([load_mrclam(mrclam7, 3)[0]])
    short = f"about {round(100 * (1 - fit.v_scale))} % short"
    assert short == "about 13 % short" and round(fit.lag_s, 1) == 0.3
    nine, ten = notebook("09-trust-the-ellipses.ipynb"), notebook("10-real-robots.ipynb")
    assert short in ten and short in nine.replace("\n  ", " ")
    assert f"lags\n  the commands by about {fit.lag_s:.1f} s" in nine


def test_notebook_13_says_what_its_robots_and_its_filter_do() -> None:
    """Its simulated team as its cells make it: robot 1 sees no other robot; one sighting of a
    robot whose heading is uncorrelated leaves that heading's σ as it was (H_b's zero column),
    and a sighting the other way shrinks it; and the whole of Dataset 7 is replayed."""
    import numpy as np

    from ekfslam.core.filter.team import TeamEKF
    from ekfslam.core.models import robot_observation
    from ekfslam.sim.config import SimulationConfig
    from ekfslam.sim.team import simulate_team

    path = ROOT / "notebooks" / "13-five-robots-one-map.ipynb"
    flat = " ".join(prose(path).split())
    cells = json.loads(path.read_text(encoding="utf-8"))["cells"]
    code = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
    assert "simulate_team((0.5, 0.75, 1.0), SimulationConfig(laps=1, seed=1))" in code
    team = simulate_team((0.5, 0.75, 1.0), SimulationConfig(laps=1, seed=1))
    assert "Robot 1 saw no other robot" in flat and 1 not in set(team.sightings.observer)
    assert (3, 1) in team.sightings.pairs()  # "the moment robot 3 first sees robot 1"

    assert "one sighting says nothing directly about the seen robot's heading" in flat
    ekf = TeamEKF()
    ekf.add_robot(1, [0.3, 0.1, 0.2], np.diag([0.15, 0.15, 0.1]) ** 2)
    ekf.add_robot(3, [0.5, -0.4, 1.6], np.diag([0.005, 0.005, 0.005]) ** 2)
    before = ekf.pose_covariance(1)[2, 2]
    ekf.update_robot(
        3, 1, robot_observation(ekf.pose(3), ekf.pose(1)) + np.array([0.01, 0.0]), np.eye(2) * 4e-4
    )
    assert ekf.pose_covariance(1)[2, 2] == before
    ekf.update_robot(1, 3, robot_observation(ekf.pose(1), ekf.pose(3)), np.eye(2) * 4e-4)
    assert ekf.pose_covariance(1)[2, 2] < before / 4

    assert "The whole dataset is replayed" in flat and "truncate" not in code
