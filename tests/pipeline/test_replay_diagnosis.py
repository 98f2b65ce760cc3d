"""Every replay diagnoses itself (`ReplayResult.diagnosis`): the seed runs agree with their data,
a replay with absurdly small noise does not (the command line's side:
tests/integration/test_cli_diagnosis.py)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from ekfslam.core.noise import NoiseConfig
from ekfslam.logs.mrclam.load import load_mrclam
from ekfslam.logs.runlog import read_run
from ekfslam.pipeline import replay

RUNS = Path(__file__).resolve().parents[2] / "data" / "runs"

SEED_RUNS = ("square-2laps", "octagon-2laps", "square-2laps-realistic", "octagon-2laps-realistic")


@pytest.mark.parametrize("name", SEED_RUNS)
def test_the_seed_runs_are_ok(name) -> None:
    d = replay(read_run(RUNS / name)).diagnosis
    assert d.verdict == "ok", d.reasons
    assert d.outlier_share < 0.02


def test_the_square_with_a_tiny_q_is_not_ok_and_says_why() -> None:
    run = read_run(RUNS / "square-2laps")
    d = replay(run, NoiseConfig(sigma_range=0.001, sigma_bearing=0.001)).diagnosis
    assert d.verdict == "lost"
    assert d.outlier_share > 0.5
    assert d.advice.endswith("try --noise fit")


def _hundredth(noise: NoiseConfig) -> NoiseConfig:
    return dataclasses.replace(
        noise,
        **{
            f: getattr(noise, f) / 100
            for f in ("sigma_x", "sigma_y", "sigma_theta", "sigma_range", "sigma_bearing")
        },
    )


def test_dataset7_robot1_with_every_sigma_divided_by_100_is_lost(mrclam7) -> None:
    run, _ = load_mrclam(mrclam7, 1)
    d = replay(run, _hundredth(run.meta.noise_defaults)).diagnosis
    assert d.verdict == "lost"
    assert d.lost_after is not None and d.lost_after < 10.0  # from the first seconds
    assert d.outlier_share > 0.99
