"""The seed's runs travel in every build of the package: setup.py's build_py copies each run of
``data/runs`` into ``ekfslam/runs``, where `ekfslam.places.seed_run` looks first."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from ekfslam import places

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_a_build_holds_the_seed_runs_and_seed_run_finds_them(tmp_path, monkeypatch) -> None:
    build = tmp_path / "lib"
    subprocess.run(
        [sys.executable, "setup.py", "-q", "build_py", "--build-lib", str(build)],
        cwd=ROOT,
        check=True,
        capture_output=True,
    )
    runs = build / "ekfslam" / "runs"
    wanted = sorted(p.name for p in (ROOT / "data" / "runs").iterdir() if p.is_dir())
    assert sorted(p.name for p in runs.iterdir()) == wanted
    for name in wanted:
        files = sorted(p.name for p in (ROOT / "data" / "runs" / name).iterdir())
        assert sorted(p.name for p in (runs / name).iterdir()) == files
    monkeypatch.setattr(places, "INSTALLED_RUNS", runs)
    assert places.seed_run("octagon-2laps-7hz") == runs / "octagon-2laps-7hz"


def test_without_an_installed_copy_seed_run_is_the_checkouts(monkeypatch, tmp_path) -> None:
    monkeypatch.setattr(places, "INSTALLED_RUNS", tmp_path / "none")
    assert places.seed_run("square-2laps") == ROOT / "data" / "runs" / "square-2laps"
