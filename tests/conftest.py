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
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

import generated
import matplotlib
import pytest
from hypothesis import HealthCheck, settings

from ekfslam.errors import InputError
from ekfslam.logs.mrclam.load import find_dataset
from ekfslam.places import shared_data_dir

matplotlib.use("Agg")  # tests never open windows, whatever the user's backend

# The generated tests' budget (tests/generated.py): a fixed number of examples in CI, derandomised
# so CI sees the same cases every run; EKFSLAM_HYPOTHESIS=long for a longer, random search.
_QUIET = [HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.function_scoped_fixture]
settings.register_profile(
    "ci",
    max_examples=generated.CI_EXAMPLES,
    deadline=None,  # a slow machine is not a failure; `generated.within` bounds each case
    derandomize=True,
    database=None,  # nothing written into the checkout
    suppress_health_check=_QUIET,
)
settings.register_profile(
    "long",
    max_examples=generated.LONG_EXAMPLES,
    deadline=None,
    database=None,
    suppress_health_check=_QUIET,
)
settings.load_profile(os.environ.get("EKFSLAM_HYPOTHESIS", "ci"))

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA_FIXTURES = frozenset({"shared_data", "mrclam7"})


def _in_ci() -> bool:
    return os.environ.get("CI", "").lower() in {"1", "true", "yes"}


def skip_or_fail_in_ci(message: str) -> NoReturn:
    """Data a test needs is not here: skip with `message`, or fail with it in CI."""
    if _in_ci():
        pytest.fail(message + "; CI must have it", pytrace=False)
    pytest.skip(message)


_MADE: list[str] = []  # the counts folder this session made


def pytest_configure(config: pytest.Config) -> None:
    """The folder every pytest process (xdist workers too) writes its generated-case counts to."""
    if not hasattr(config, "workerinput") and generated.COUNTS_DIR_ENV not in os.environ:
        _MADE.append(tempfile.mkdtemp(prefix="ekfslam-generated-"))
        os.environ[generated.COUNTS_DIR_ENV] = _MADE[0]


def pytest_sessionfinish(session: pytest.Session) -> None:
    generated.write_counts()


def pytest_terminal_summary(terminalreporter, config: pytest.Config) -> None:
    """How many generated cases each reader and API function saw (tests/generated.py)."""
    generated.write_counts()  # this process's (without xdist, the only one)
    folder = os.environ.get(generated.COUNTS_DIR_ENV)
    counts = generated.read_counts(Path(folder)) if folder else {}
    if folder in _MADE:  # made by this session, not given
        shutil.rmtree(folder, ignore_errors=True)
    if not counts:
        return
    profile = os.environ.get("EKFSLAM_HYPOTHESIS", "ci")
    terminalreporter.section(f"generated cases (hypothesis profile {profile!r})")
    for target, n in sorted(counts.items()):
        terminalreporter.write_line(f"{n:7d}  {target}")
    terminalreporter.write_line(f"{sum(counts.values()):7d}  in all")


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
