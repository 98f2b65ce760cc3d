"""Shared test fixtures.

Real recorded data (UTIAS MRCLAM) is read from one configurable folder, never copied into the
repo: ``EKFSLAM_SHARED_DATA`` if set, else ``../shared/data`` beside the checkout. Where it is
absent the tests that need it skip with a reason; in CI (``CI=true``) its absence is a failure.
"""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")  # tests never open windows, whatever the user's backend

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("EKFSLAM_SHARED_DATA", REPO.parent / "shared" / "data"))


def _in_ci() -> bool:
    return os.environ.get("CI", "").lower() in {"1", "true", "yes"}


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The shared data folder; skips (or fails, in CI) when it is not there."""
    if not SHARED_DATA.is_dir():
        message = f"shared data folder {SHARED_DATA} not found (set EKFSLAM_SHARED_DATA)"
        if _in_ci():
            pytest.fail(message + "; CI must have it")
        pytest.skip(message)
    return SHARED_DATA


@pytest.fixture(scope="session")
def mrclam7(shared_data: Path) -> Path:
    """The MRCLAM Dataset 7 folder inside the shared data."""
    path = shared_data / "mrclam" / "MRCLAM_Dataset7"
    if not path.is_dir():
        message = f"MRCLAM Dataset 7 not found at {path}"
        if _in_ci():
            pytest.fail(message + "; CI must have it")
        pytest.skip(message)
    return path
