"""The compiled filter's cache keeps the digests last used, not one copy per edit of a model."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from ekfslam.core.filter import backend, compile
from ekfslam.core.models import ODOMETRY, RANGE_BEARING

HOUR = 3600.0


def digest(i: int) -> str:
    return f"{i:016x}"


def cached_files(folder: Path, tag: str) -> list[Path]:
    """What one digest leaves: numba's index and machine code of a step, the generated step."""
    names = [f"steps.sight_{tag}-496.py311.nbi", f"steps.sight_{tag}-496.py311.1.nbc"]
    names.append(f"ekfslam_generated_advance_{tag}.py")
    return [folder / name for name in names]


def make(folder: Path, tag: str, age_s: float) -> None:
    then = time.time() - age_s
    for path in cached_files(folder, tag):
        path.write_bytes(b"x")
        os.utime(path, (then, then))


@pytest.fixture
def folder(tmp_path: Path, monkeypatch) -> Path:
    monkeypatch.setattr(compile, "_cache_dir", lambda: tmp_path)  # where the markers go
    return tmp_path


def test_prune_keeps_the_last_used_digests_and_the_one_in_use(folder: Path) -> None:
    for i in range(12):  # digest 0 the newest; all unused for over an hour
        make(folder, digest(i), 2 * HOUR + 60 * i)
    others = [folder / "compile._dot-113.py311.nbi", folder / "steps.cpython-311.pyc"]
    for path in others:
        path.write_bytes(b"x")
    (folder / f"ekfslam_used_{digest(11)}.stamp").touch()  # the oldest is used now (`compiled`)
    deleted = compile.prune({folder}, digest(11))
    kept = {digest(11), *(digest(i) for i in range(compile.KEEP_DIGESTS - 1))}
    for i in range(12):
        present = [p.exists() for p in cached_files(folder, digest(i))]
        assert present == [digest(i) in kept] * 3, i
    assert len(deleted) == 3 * (12 - compile.KEEP_DIGESTS)
    assert all(path.exists() for path in others)  # files without a digest are not the cache's


def test_a_digest_used_within_the_hour_is_kept_whatever_its_rank(folder: Path) -> None:
    for i in range(2 * compile.KEEP_DIGESTS):
        make(folder, digest(i), 60.0 * i)  # another process may be loading any of them
    assert compile.prune({folder}, digest(0)) == []


def test_a_marker_counts_as_use(folder: Path) -> None:
    for i in range(compile.KEEP_DIGESTS + 1):
        make(folder, digest(i), 2 * HOUR + i)
    marker = folder / f"ekfslam_used_{digest(compile.KEEP_DIGESTS)}.stamp"
    marker.touch()  # the oldest files, but a process made its steps a moment ago
    compile.prune({folder}, digest(99))
    assert all(p.exists() for p in cached_files(folder, digest(compile.KEEP_DIGESTS)))


def test_the_compiled_steps_prune_the_folders_numba_caches_them_in(monkeypatch) -> None:
    seen = []
    monkeypatch.setattr(compile, "prune", lambda folders, tag: seen.append((folders, tag)))
    steps = compile.compiled(backend.ROOTS, {"motion": ODOMETRY, "sensor": RANGE_BEARING})
    ((folders, tag),) = seen
    assert time.time() - (compile._cache_dir() / f"ekfslam_used_{tag}.stamp").stat().st_mtime < 60
    numba_folder = Path(steps.sight._dispatcher._cache.cache_path)
    assert numba_folder in folders and compile._cache_dir() in folders
    assert tag in steps.sight.py_func.__qualname__
