"""``lab grade --dask ADDRESS``: a class graded on a Dask cluster's workers, each exercise still
in a sandbox on the worker, with the same CSV as graded here."""

from __future__ import annotations

import csv
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ekfslam.cli.lab_sandbox import unavailable


@pytest.mark.slow
def test_a_class_graded_on_a_dask_cluster_matches_the_local_grades(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    if unavailable() is not None:
        pytest.skip(f"no sandbox on this machine: {unavailable()}")
    lab = [sys.executable, "-m", "ekfslam", "lab"]
    subprocess.run([*lab, "release", "handout"], cwd=tmp_path, check=True, capture_output=True)
    for student, source in (("alice", "lab-course/source"), ("bob", "handout")):
        (tmp_path / "subs" / student).mkdir(parents=True)
        shutil.copy(tmp_path / source / "02-robot-and-arena.ipynb", tmp_path / "subs" / student)
    grade = [*lab, "grade", "subs"]
    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=2, processes=True, dashboard_address=None
    ) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tcp://")
        done = subprocess.run(
            [*grade, "--csv", "dask.csv", "--dask", address],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=900,
        )
    assert done.returncode == 0, done.stderr[-3000:]
    local = subprocess.run(
        [*grade, "--csv", "local.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=900
    )
    assert local.returncode == 0, local.stderr[-3000:]

    def rows(name: str) -> dict[str, dict[str, str]]:
        return {r["student"]: r for r in csv.DictReader((tmp_path / name).open(encoding="utf-8"))}

    on_dask, here = rows("dask.csv"), rows("local.csv")
    assert on_dask == here
    assert (on_dask["alice"]["1a"], on_dask["bob"]["1a"]) == ("1", "0")
    assert on_dask["alice"]["sandbox"] == "bubblewrap"
