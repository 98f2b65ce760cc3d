"""Shared test fixtures.

Real recorded data (UTIAS MRCLAM) is read from one configurable folder, never copied into the
repo: `ekfslam.places.shared_data_dir()`, i.e. ``EKFSLAM_SHARED_DATA`` if set, else
``../shared/data`` beside the checkout. MRCLAM Dataset 7 is found as the package finds it
(`ekfslam.logs.mrclam.load.find_dataset`): there, else in the cache of ``python -m ekfslam fetch
mrclam 7``. Where it is absent the tests that need it skip with a reason; in CI (``CI=true``) its
absence is a failure. Every test that uses the ``shared_data`` or ``mrclam7`` fixture is marked
``shared_data`` automatically, so ``-m "not shared_data"`` deselects it.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

import matplotlib
import pytest

from ekfslam.errors import InputError
from ekfslam.logs.mrclam.load import find_dataset
from ekfslam.places import shared_data_dir

matplotlib.use("Agg")  # tests never open windows, whatever the user's backend

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA_FIXTURES = frozenset({"shared_data", "mrclam7"})


def _in_ci() -> bool:
    return os.environ.get("CI", "").lower() in {"1", "true", "yes"}


def skip_or_fail_in_ci(message: str) -> NoReturn:
    """Data a test needs is not here: skip with `message`, or fail with it in CI."""
    if _in_ci():
        pytest.fail(message + "; CI must have it", pytrace=False)
    pytest.skip(message)


@pytest.hookimpl(tryfirst=True)  # before -m deselects by mark
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if SHARED_DATA_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.shared_data)


@pytest.fixture(scope="session")
def data_missing() -> Callable[[str], NoReturn]:
    """`skip_or_fail_in_ci`, for tests that find out themselves that data is missing."""
    return skip_or_fail_in_ci


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared data folder; skips (or fails, in CI) when it is not there."""
    folder = shared_data_dir()
    if folder is None or not folder.is_dir():
        skip_or_fail_in_ci(f"shared data folder {folder} not found (set EKFSLAM_SHARED_DATA)")
    return folder


@pytest.fixture(scope="session")
def mrclam7() -> Path:
    """MRCLAM Dataset 7, where the package finds it: the shared data, else the download cache
    of ``python -m ekfslam fetch mrclam 7`` (`ekfslam.logs.mrclam.load.find_dataset`)."""
    try:
        return find_dataset(7)
    except InputError as missing:
        skip_or_fail_in_ci(
            f"MRCLAM Dataset 7 is in neither {shared_data_dir()}/mrclam nor {missing.path}: run "
            "`python -m ekfslam fetch mrclam 7`, or set EKFSLAM_SHARED_DATA"
        )


RUNS = REPO / "data" / "runs"


@pytest.fixture(scope="module")
def square():
    """The seed's square run, ``data/runs/square-2laps`` (read once per test module)."""
    from ekfslam.logs.runlog import read_run

    return read_run(RUNS / "square-2laps")


@pytest.fixture(scope="module")
def square_result(square):
    """Its replay with the run's default noise."""
    from ekfslam.pipeline import replay

    return replay(square)
