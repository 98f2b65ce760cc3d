"""Files written whole or not at all: a failed or interrupted write never leaves half a file.

Every file ekfslam writes as a result (figures, tables, exports) goes through `atomic_write`:
a temporary file beside the target, renamed onto it once complete.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any


def atomic_write(path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
    """Have ``write(tmp)`` write a temporary file beside `path`, then rename it onto `path`.

    The rename is atomic on one file system, so `path` is either the old file or the complete
    new one: a failure inside `write` (or an interrupt) removes the temporary file and leaves an
    existing `path` untouched. Missing parent folders are created. The temporary file keeps
    `path`'s suffix, so writers that pick a format from the name (matplotlib) still can.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(
        prefix=f".{path.name}.", suffix=f".partial{path.suffix}", dir=path.parent
    )
    os.close(fd)
    tmp = Path(name)
    try:
        write(tmp)
        # mkstemp's file is private (0600); give it the mode the file has or a new one would get
        os.chmod(tmp, path.stat().st_mode & 0o777 if path.exists() else 0o666 & ~_umask())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def _umask() -> int:
    mask = os.umask(0o022)  # the only portable way to read it is to set it
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write `text` (UTF-8, ``\\n`` line ends) to `path` atomically (see `atomic_write`)."""
    return atomic_write(path, lambda tmp: tmp.write_text(text, encoding="utf-8", newline="\n"))


def save_figure(fig: Any, path: str | os.PathLike, dpi: int = 120) -> Path:
    """``fig.savefig`` to `path` atomically, in the format its suffix names."""
    fmt = Path(path).suffix.lstrip(".").lower() or None
    return atomic_write(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi))
