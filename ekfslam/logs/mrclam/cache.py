"""Where a MRCLAM dataset lives once fetched: the cache folder, a dataset's folder in it, and the
files a complete dataset holds. Plain paths, no network code: `ekfslam.logs.mrclam.load` finds a
dataset through these without loading `ekfslam.logs.mrclam.fetch`'s downloader (urllib, a tenth
of the start-up of ``run``)."""

from __future__ import annotations

import os
from pathlib import Path

from ekfslam.errors import ConfigError

DATASETS = range(1, 10)
EXPECTED_FILES = (
    "Barcodes.dat",
    "Landmark_Groundtruth.dat",
    *(
        f"Robot{r}_{kind}.dat"
        for r in range(1, 6)
        for kind in ("Odometry", "Measurement", "Groundtruth")
    ),
)
#: What `default_cache_dir` picks, for help texts (the dataset goes in <cache>/mrclam/...).
CACHE_DEFAULT_HELP = "$EKFSLAM_CACHE, else $XDG_CACHE_HOME/ekfslam, else ~/.cache/ekfslam"


def default_cache_dir() -> Path:
    """``$EKFSLAM_CACHE``, else ``$XDG_CACHE_HOME/ekfslam``, else ``~/.cache/ekfslam``."""
    if os.environ.get("EKFSLAM_CACHE"):
        return Path(os.environ["EKFSLAM_CACHE"]).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "ekfslam"


def mrclam_path(n: int, cache_dir: str | Path | None = None) -> Path:
    """Where dataset n lives once fetched: ``<cache>/mrclam/MRCLAM_Dataset<n>``."""
    cache = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    return cache / "mrclam" / f"MRCLAM_Dataset{dataset_number(n)}"


def missing_files(folder: str | Path) -> list[str]:
    """The expected MRCLAM file names that are not in `folder` (all of them if it is absent)."""
    folder = Path(folder)
    return [name for name in EXPECTED_FILES if not (folder / name).is_file()]


def dataset_number(n: int) -> int:
    """n, if it numbers a MRCLAM dataset (1 to 9)."""
    if isinstance(n, bool) or not isinstance(n, int) or n not in DATASETS:
        raise ConfigError(f"MRCLAM datasets are numbered 1 to 9, got {n!r}")
    return n
