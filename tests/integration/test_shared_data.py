"""Where shared data is found, what happens without it, and which tests say they need it.

Shared data (MRCLAM) is found in one place, `ekfslam.places.shared_data_dir()`, by the
package and by the tests' fixtures (tests/conftest.py). Without it, notebooks stop in one line and
the tests that need it skip with a reason (fail in CI), and ``-m "not shared_data"`` leaves every
one of them out.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import ekfslam.places as places
from ekfslam.errors import InputError
from ekfslam.logs.mrclam.load import find_dataset
from ekfslam.places import shared_data_dir
from ekfslam.teaching.lessons import NotebookStop, mrclam_dataset

REPO = Path(__file__).resolve().parents[2]


def fake_dataset(folder: Path) -> Path:
    folder.mkdir(parents=True)
    (folder / "Barcodes.dat").write_text("# a stand-in: find_dataset only looks for this file\n")
    return folder


@pytest.fixture
def nowhere(monkeypatch, tmp_path: Path) -> Path:
    """No shared data and an empty download cache; returns the cache folder."""
    monkeypatch.setenv("EKFSLAM_SHARED_DATA", str(tmp_path / "no-shared-data"))
    monkeypatch.setenv("EKFSLAM_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def test_the_variable_replaces_the_folder_beside_the_checkout(monkeypatch, tmp_path: Path):
    monkeypatch.delenv("EKFSLAM_SHARED_DATA", raising=False)
    assert shared_data_dir() == REPO.parent / "shared" / "data"  # a source checkout
    monkeypatch.setenv("EKFSLAM_SHARED_DATA", str(tmp_path / "elsewhere"))
    assert shared_data_dir() == tmp_path / "elsewhere"  # even though it does not exist


def test_an_installed_package_has_no_folder_beside_it(monkeypatch, tmp_path: Path):
    monkeypatch.delenv("EKFSLAM_SHARED_DATA", raising=False)
    site = tmp_path / "lib" / "python3.11" / "site-packages"
    monkeypatch.setattr(places, "__file__", str(site / "ekfslam" / "places.py"))
    assert shared_data_dir() is None


def test_find_dataset_looks_in_the_shared_folder_then_the_cache(nowhere: Path, tmp_path: Path):
    """Regression: with EKFSLAM_SHARED_DATA set, ../shared was still searched behind it."""
    with pytest.raises(InputError, match=r"dataset 7 not found; run `python -m ekfslam fetch"):
        find_dataset(7)
    cached = fake_dataset(nowhere / "mrclam" / "MRCLAM_Dataset7")
    assert find_dataset(7) == cached
    shared = fake_dataset(tmp_path / "shared" / "mrclam" / "MRCLAM_Dataset7")
    os.environ["EKFSLAM_SHARED_DATA"] = str(tmp_path / "shared")  # monkeypatch restores it
    assert find_dataset(7) == shared


def test_a_notebook_without_the_data_stops_with_one_line(nowhere: Path):
    with pytest.raises(NotebookStop) as stop:
        mrclam_dataset(7)
    (line,) = stop.value._render_traceback_()  # what IPython shows instead of a traceback
    assert "MRCLAM Dataset 7" in line and "`python -m ekfslam fetch mrclam 7`" in line
    assert "\n" not in line
    fetched = fake_dataset(nowhere / "mrclam" / "MRCLAM_Dataset7")
    assert mrclam_dataset(7) == fetched


_RECORDER = """
import json, os

KEPT, DESELECTED = [], []


def _row(item):
    return {"id": item.nodeid, "fixtures": sorted(getattr(item, "fixturenames", ())),
            "marks": sorted({m.name for m in item.iter_markers()})}


def pytest_deselected(items):
    DESELECTED.extend(_row(i) for i in items)


def pytest_collection_finish(session):
    KEPT.extend(_row(i) for i in session.items)
    with open(os.environ["EKFSLAM_COLLECTED"], "w") as out:
        json.dump({"kept": KEPT, "deselected": DESELECTED}, out)
"""


@pytest.mark.slow
def test_every_test_that_reads_shared_data_is_marked_and_deselectable(tmp_path: Path):
    """Collect the whole suite with -m "not shared_data" and look at every item."""
    (tmp_path / "record_items.py").write_text(_RECORDER)
    env = {
        **os.environ,
        "EKFSLAM_COLLECTED": str(tmp_path / "items.json"),
        "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")]),
    }
    args = ["--collect-only", "-q", "-p", "record_items", "-p", "no:cacheprovider"]
    out = subprocess.run(
        [sys.executable, "-m", "pytest", *args, "-m", "not shared_data", "tests"],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    items = json.loads((tmp_path / "items.json").read_text())
    kept, deselected = items["kept"], items["deselected"]
    needs = lambda row: {"shared_data", "mrclam7"} & set(row["fixtures"])  # noqa: E731
    users = [row for row in kept + deselected if needs(row)]
    assert len(users) > 50  # the MRCLAM tests, fetch, filter, consistency, ...
    unmarked = [row["id"] for row in users if "shared_data" not in row["marks"]]
    assert not unmarked, f"use shared data but are not marked shared_data: {unmarked}"
    assert not [row["id"] for row in kept if needs(row)]
    notebooks = {
        row["id"].split("[")[-1] for row in deselected if "test_notebook_executes" in row["id"]
    }
    assert notebooks == {
        "09-trust-the-ellipses.ipynb]",
        "10-real-robots.ipynb]",
        "13-five-robots-one-map.ipynb]",
    }
