"""Where the data is: the seed's runs (installed with the package, or the checkout's), the
source checkout, and the shared data folder.

The one module that looks outside the installed package. In a source checkout (this package's
parent folder holds ``pyproject.toml``) the seed's runs are ``data/runs/`` of the checkout and
the shared data folder is ``shared/data`` beside the checkout; ``$EKFSLAM_SHARED_DATA`` names
another shared data folder. Installed as a wheel there is no checkout: `checkout` and
`seed_runs_dir` return None, and so does `shared_data_dir` unless the variable is set. Callers
take a folder as an argument and use these only as its default.
"""

from __future__ import annotations

import os
from pathlib import Path

#: Names the shared data folder (MRCLAM datasets in its ``mrclam/``); it wins over the checkout's.
SHARED_DATA_ENV = "EKFSLAM_SHARED_DATA"


def checkout() -> Path | None:
    """The source checkout this package is imported from, or None when it is installed."""
    root = Path(__file__).resolve().parent.parent  # ekfslam/places.py -> the checkout
    return root if (root / "pyproject.toml").is_file() else None


def seed_runs_dir() -> Path | None:
    """``data/runs`` of the source checkout (the seed's runs; it may not exist), or None."""
    root = checkout()
    return root / "data" / "runs" if root is not None else None


def shared_data_dir() -> Path | None:
    """The shared data folder (it may not exist): ``$EKFSLAM_SHARED_DATA`` if set, else
    ``shared/data`` beside a source checkout, else None (an installed package has no checkout).

    `ekfslam.logs.mrclam.load.find_dataset` looks here before the download cache, and so do the
    tests' fixtures.
    """
    if os.environ.get(SHARED_DATA_ENV):
        return Path(os.environ[SHARED_DATA_ENV]).expanduser()
    root = checkout()
    return root.parent / "shared" / "data" if root is not None else None


#: The seed's runs inside an installed package: package data built from ``data/runs``.
INSTALLED_RUNS = Path(__file__).resolve().parent / "runs"


def seed_run(name: str) -> Path:
    """The folder of the seed's run `name` (``square-2laps``, ``octagon-2laps``, ...) where a
    notebook reads it: installed with the package (``ekfslam/runs/``, which every wheel holds,
    built from the checkout's ``data/runs``), else the source checkout's ``data/runs/`` (an
    editable install, or ``PYTHONPATH`` at a checkout). A notebook that asks for its runs by name
    needs no path, so it runs copied anywhere: out of the repository, in a lab release, on Colab.
    The folder may not exist (a name that is no run): `ekfslam.logs.runlog.read_run` says so."""
    installed = INSTALLED_RUNS / name
    if installed.is_dir():
        return installed
    runs = seed_runs_dir()
    return (runs if runs is not None else INSTALLED_RUNS) / name
