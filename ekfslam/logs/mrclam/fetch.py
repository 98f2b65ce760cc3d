"""Download the UTIAS MRCLAM datasets from their publisher into a local cache.

The nine datasets are served as ``MRCLAM<N>.zip`` from ``ftp://asrl3.utias.utoronto.ca/MRCLAM/``
(listed on http://asrl.utias.utoronto.ca/datasets/mrclam/). Each one unpacks, checked, to
``<cache>/mrclam/MRCLAM_Dataset<N>/`` whatever the folder inside the archive is called (dataset 4's
is ``MRSLAM_Dataset4``), ready for `ekfslam.logs.mrclam.load.load_mrclam`.

Environment: ``EKFSLAM_MRCLAM_URL`` replaces the base URL (a mirror; http, https and ftp work),
``EKFSLAM_CACHE`` the cache folder (default ``$XDG_CACHE_HOME/ekfslam``, else ``~/.cache/ekfslam``).
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import urllib.error
import urllib.request
import zipfile
from pathlib import Path, PurePosixPath
from typing import TextIO

from ekfslam.errors import ConfigError, EkfSlamError
from ekfslam.logs.mrclam.cache import dataset_number, missing_files, mrclam_path

DEFAULT_BASE_URL = "ftp://asrl3.utias.utoronto.ca/MRCLAM/"
DATASET_PAGE = "http://asrl.utias.utoronto.ca/datasets/mrclam/"
TIMEOUT_S = 60.0
_CHUNK = 1 << 16


class FetchError(EkfSlamError):
    """A dataset could not be downloaded, unpacked or checked; the message says what to do."""


def mrclam_url(n: int, base_url: str | None = None) -> str:
    """The archive URL of dataset n: base URL (argument, ``$EKFSLAM_MRCLAM_URL`` or default)."""
    base = base_url or os.environ.get("EKFSLAM_MRCLAM_URL") or DEFAULT_BASE_URL
    return f"{base.rstrip('/')}/MRCLAM{_check_number(n)}.zip"


def fetch_mrclam(
    n: int,
    *,
    cache_dir: str | Path | None = None,
    base_url: str | None = None,
    progress: bool = True,
    stream: TextIO | None = None,
) -> Path:
    """Download, unpack and check MRCLAM dataset `n` (1-9) once; return its folder.

    A folder already in the cache with all 17 files is returned without any network access.
    Otherwise the archive is downloaded to a temporary file in the cache, unpacked into a
    temporary folder there (member names that would escape it are refused), checked, and only
    then renamed into place, so an interrupted or failed fetch never leaves a half dataset where
    `load_mrclam` would find it.

    Parameters
    ----------
    n : dataset number, 1 to 9.
    cache_dir : cache root; default `ekfslam.logs.mrclam.cache.default_cache_dir`.
    base_url : folder URL holding ``MRCLAM<n>.zip``; default ``$EKFSLAM_MRCLAM_URL`` or the
        publisher's FTP server.
    progress : draw a text progress bar.
    stream : where the bar goes; default sys.stderr. Nothing else is printed.

    Returns
    -------
    Path ``<cache>/mrclam/MRCLAM_Dataset<n>``.

    Raises
    ------
    FetchError
        Bad dataset number, download failure, not a zip, unsafe member name, files missing.
    """
    final = mrclam_path(_check_number(n), cache_dir)
    if not missing_files(final):
        return final
    url = mrclam_url(n, base_url)
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FetchError(f"cannot create the cache folder {final.parent}: {exc.strerror}") from None
    out = (stream if stream is not None else sys.stderr) if progress else None
    archive = _download(url, final, out)
    try:
        staging = Path(tempfile.mkdtemp(prefix=f".{final.name}-", dir=final.parent))
        try:
            folder = _unpack(archive, staging, url)
            _move_into_place(folder, final)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    finally:
        archive.unlink(missing_ok=True)
    return final


def _check_number(n: int) -> int:
    """`ekfslam.logs.mrclam.cache.dataset_number`, refused as a `FetchError`."""
    try:
        return dataset_number(n)
    except ConfigError as exc:
        raise FetchError(str(exc)) from None


def _download(url: str, final: Path, out: TextIO | None) -> Path:
    """Stream `url` to a temporary file beside `final`; deleted again on any failure."""
    name = url.rsplit("/", 1)[-1]
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{name}-", suffix=".part", dir=final.parent)
    except OSError as exc:
        raise FetchError(f"cannot write into the cache folder {final.parent}: {exc}") from None
    tmp = Path(tmp_name)
    try:
        with os.fdopen(fd, "wb") as sink, urllib.request.urlopen(url, timeout=TIMEOUT_S) as src:
            length = src.headers.get("Content-Length")
            total = int(length) if length and length.isdigit() else None
            bar = _ProgressBar(name, total, out)
            received = 0
            while chunk := src.read(_CHUNK):
                sink.write(chunk)
                received += len(chunk)
                bar.update(received)
            bar.close()
        if total is not None and received != total:
            raise OSError(f"connection closed after {received} of {total} bytes")
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, urllib.error.URLError | OSError | ValueError):
            raise FetchError(_download_advice(url, _reason(exc), final)) from None
        raise
    return tmp


def _reason(exc: BaseException) -> str:
    if isinstance(exc, urllib.error.HTTPError):
        return f"HTTP {exc.code} {exc.reason}"
    if isinstance(exc, urllib.error.URLError):
        return str(exc.reason)
    return str(exc) or type(exc).__name__


def _download_advice(url: str, reason: str, final: Path) -> str:
    return (
        f"could not download {url}: {reason}; check the network, set EKFSLAM_MRCLAM_URL to a "
        f"mirror, or download {url.rsplit('/', 1)[-1]} by hand (from {DATASET_PAGE}) and unzip "
        f"its files into {final}"
    )


def _unpack(archive: Path, staging: Path, url: str) -> Path:
    """Extract into `staging` and return the folder that holds the dataset's files."""
    try:
        with zipfile.ZipFile(archive) as zf:
            for member in zf.infolist():
                _check_member(member.filename, url)
            zf.extractall(staging)
    except zipfile.BadZipFile:
        raise FetchError(f"{url} is not a zip archive (damaged download?)") from None
    except OSError as exc:
        raise FetchError(f"cannot unpack {url} into {staging}: {exc}") from None
    # the files sit at the top, in MRCLAM_Dataset<N>/, or (dataset 4) in MRSLAM_Dataset4/
    candidates = sorted(
        (p.parent for p in staging.rglob("Barcodes.dat") if "__MACOSX" not in p.parts),
        key=lambda p: len(p.parts),
    )
    folder = candidates[0] if candidates else staging
    missing = missing_files(folder)
    if missing:
        raise FetchError(
            f"{url} does not hold a complete MRCLAM dataset: missing {', '.join(missing)}"
        )
    return folder


def _check_member(name: str, url: str) -> None:
    """Refuse names that would land outside the extraction folder (zip slip)."""
    path = PurePosixPath(name.replace("\\", "/"))
    if path.is_absolute() or ".." in path.parts or (path.parts and ":" in path.parts[0]):
        raise FetchError(f"{url} contains an unsafe file name {name!r}; refusing to unpack it")


def _move_into_place(folder: Path, final: Path) -> None:
    """Rename the checked folder to `final`, replacing an incomplete one already there."""
    old = None
    if final.exists():
        old = final.with_name(f".{final.name}-old-{os.getpid()}")
        shutil.rmtree(old, ignore_errors=True)
        final.rename(old)
    try:
        folder.rename(final)
    except OSError as exc:
        if missing_files(final):  # not another process finishing the same fetch first
            raise FetchError(f"cannot move the dataset into {final}: {exc}") from None
    finally:
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)


class _ProgressBar:
    """``MRCLAM7.zip [#######.............]  35%  8.8/25.0 MB``, redrawn in place with \\r."""

    WIDTH = 30

    def __init__(self, name: str, total: int | None, out: TextIO | None) -> None:
        self.name, self.total, self.out = name, total, out
        self.shown = -1

    def update(self, received: int) -> None:
        if self.out is None:
            return
        mb = received / 1e6
        if self.total:
            percent = min(100, received * 100 // self.total)
            if percent == self.shown:
                return
            self.shown = percent
            filled = self.WIDTH * percent // 100
            bar = "#" * filled + "." * (self.WIDTH - filled)
            text = f"{self.name} [{bar}] {percent:3d}%  {mb:.1f}/{self.total / 1e6:.1f} MB"
        else:
            tenths = int(mb * 10)
            if tenths == self.shown:
                return
            self.shown = tenths
            text = f"{self.name} {mb:.1f} MB"
        self.out.write("\r" + text)
        self.out.flush()

    def close(self) -> None:
        if self.out is not None and self.shown >= 0:
            self.out.write("\n")
            self.out.flush()
