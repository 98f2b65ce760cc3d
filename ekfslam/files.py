"""Files written whole or not at all, to targets checked before the work, safe from signals.

Every file ekfslam writes as a result (figures, tables, runs, exports) goes through
`atomic_write`: a temporary file beside the target, renamed onto it once complete. Around that:

- `probe_output` says, before any work, whether a target can be written at all: not an empty
  path, no name longer than the file system allows, not a folder where a file belongs (or a file
  where a folder does), nothing but folders on the way, and a folder that really takes a new
  file (a probe file is created and removed: /proc, /sys, a read-only mount or a full quota say
  no there, whatever the permission bits claim). Every command's output options use it
  (`ekfslam.cli.args.output_file`, `output_folder`), and so do `write_run` and `export_tum`.
- Any OSError while writing becomes one `OutputError` naming the user's path, never the
  temporary file's.
- `new_folder`: a folder a writer creates is removed again if the writer fails or is
  interrupted, so a refused or interrupted command leaves no half-made run behind.
- `atomic_write_all`: several files that belong together (a run folder) are all written to
  temporary files first and renamed in one uninterruptible step.
- `interrupts_raise`: the command line's signal handling. SIGINT and SIGTERM raise `Interrupted`
  (a KeyboardInterrupt), so every clean-up above runs on the way out; inside `uninterrupted` a
  signal waits until the step is done.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import signal
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ekfslam.errors import Interrupted, OutputError

#: The longest part of the target's name a temporary name keeps: `tempfile` adds 8 random
#: characters and ".partial" the suffix, and the whole must stay within NAME_MAX (255).
_TEMP_STEM = 100
#: The limits of Linux's (and macOS's) usual file systems, in bytes.
_NAME_MAX, _PATH_MAX = 255, 4096


def user_path(text: str | os.PathLike) -> Path:
    """`text` as a Path, ``~`` and ``~user`` expanded where they can be (``~nobody-here/x`` is
    left as typed: pathlib would raise RuntimeError, and the path then is simply not found)."""
    path = Path(text)
    try:
        return path.expanduser()
    except RuntimeError:
        return path


# ------------------------------------------------------------------------------- probing
def output_problem(path: str | os.PathLike, *, folder: bool = False) -> str | None:
    """Why `path` cannot be written (as a file, or with `folder` as a folder to fill), or None.

    Missing parent folders are fine (the writers create them) when the nearest existing
    ancestor is a folder that takes a new file.
    """
    text = os.fspath(path)
    if not str(text).strip():
        return "an empty path; name a file or folder"
    if "\0" in str(text):
        return "the path holds a NUL character"
    path = Path(path)
    too_long = _too_long(path)
    if too_long is not None:
        return too_long
    if folder:
        if _exists(path) and not _is_dir(path):
            return f"exists and is {_kind(path)}, not a folder; choose another path"
    elif _is_dir(path):
        kind = "a link to a folder" if path.is_symlink() else "a folder"
        return f"is {kind}; name a file"
    elif _exists(path) and not path.is_file():
        return f"exists and is {_kind(path)}, not a regular file; choose another path"
    ancestor = path if folder and _is_dir(path) else path.parent
    while not _exists(ancestor) and ancestor != ancestor.parent:
        if ancestor.is_symlink():
            return f"{ancestor} is a symbolic link that leads nowhere (dangling), not a folder"
        ancestor = ancestor.parent
    if not _is_dir(ancestor):
        return f"lies under {ancestor}, which is {_kind(ancestor)}, not a folder"
    return _probe(ancestor)


def probe_output(path: str | os.PathLike, *, folder: bool = False) -> Path:
    """`path` as a Path if it can be written (`output_problem`), else `OutputError` naming it."""
    problem = output_problem(path, folder=folder)
    if problem is not None:
        raise OutputError(path, problem)
    return Path(path)


def _kind(path: Path) -> str:
    """What a path that is not a regular file is, in words (for messages)."""
    if path.is_symlink() and not path.exists():
        return "a symbolic link that leads nowhere (dangling, or a loop)"
    if path.is_dir():
        return "a folder"
    if path.is_fifo():
        return "a FIFO (a named pipe)"
    if path.is_char_device() or path.is_block_device():
        target = f" to {os.path.realpath(path)}" if path.is_symlink() else ""
        return f"a device{' (a link' + target + ')' if target else ''}"
    if path.is_socket():
        return "a socket"
    return "a file"


def _too_long(path: Path) -> str | None:
    """A name longer than file systems take (NAME_MAX, 255 bytes), or a path longer than the
    system's limit (PATH_MAX, 4096): said before anything is looked up (a lookup fails on it)."""
    for name in path.parts:
        size = len(os.fsencode(name))
        if size > _NAME_MAX:
            return f"the name {name[:40]}... is too long: {size} bytes, at most {_NAME_MAX}"
    size = len(os.fsencode(str(path.absolute())))
    if size >= _PATH_MAX:
        return f"the path is too long: {size} bytes, at most {_PATH_MAX - 1}"
    return None


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except OSError:  # a component too long, a loop of links, no permission to look
        return False


def _is_dir(path: Path) -> bool:
    try:
        return path.is_dir()
    except OSError:
        return False


def _probe(folder: Path) -> str | None:
    """Create and remove a file in `folder`: None if that worked, else why not."""
    try:
        fd, name = tempfile.mkstemp(prefix=".ekfslam-probe-", dir=folder)
    except OSError as err:
        return f"cannot write into {folder} ({_reason(err)})"
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(name)
    return None


def _reason(err: OSError) -> str:
    if err.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if err.errno == errno.EROFS:
        return "a read-only file system"
    if err.errno == errno.ENOSPC:
        return "no space left on the device"
    if err.errno == errno.ENAMETOOLONG:
        return "a name or path too long for the file system"
    if err.errno == errno.ENOENT:  # /proc, /sys: folders that take no new file
        return "this file system takes no new files there"
    return err.strerror or str(err) or type(err).__name__


def not_a_file(path: str | os.PathLike) -> str | None:
    """Why `path` cannot be read as a file, in words, or None when it is a regular file.

    Missing, a folder, a symbolic link that leads nowhere (dangling, or a loop), a FIFO (reading
    one waits forever for a writer), a device (a link to /dev/null reads as empty), a socket.
    """
    path = Path(path)
    try:
        if path.is_file():
            return None
    except OSError as err:  # a name too long, no permission to look
        return f"cannot be read ({_reason(err)})"
    if not path.exists() and not path.is_symlink():
        return "missing file"
    kind = _kind(path)
    return f"is {kind}, not a {'file' if kind == 'a folder' else 'regular file'}"


# ------------------------------------------------------------------------------- writing
def atomic_write(path: str | os.PathLike, write: Callable[[Path], object]) -> Path:
    """Have ``write(tmp)`` write a temporary file beside `path`, then rename it onto `path`.

    The rename is atomic on one file system, so `path` is either the old file or the complete
    new one: a failure inside `write` (or an interrupt) removes the temporary file and leaves an
    existing `path` untouched. Missing parent folders are created. The temporary file keeps
    `path`'s suffix, so writers that pick a format from the name (matplotlib) still can. Any
    OSError becomes an `OutputError` naming `path`.
    """
    path = Path(path)
    tmp: Path | None = None
    try:
        # the temporary file exists only where the clean-up below sees it: an interrupt held
        # back while it is made is raised on leaving the block, inside this try
        with uninterrupted():
            tmp = _temporary(path)
        write(tmp)
        # mkstemp's file is private (0600); give it the mode the file has or a new one would get
        os.chmod(tmp, path.stat().st_mode & 0o777 if path.exists() else 0o666 & ~_umask())
        with uninterrupted():
            os.replace(tmp, path)
    except OSError as err:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        if isinstance(err, OutputError):
            raise
        raise OutputError(path, f"cannot write it ({_reason(err)})") from None
    except BaseException:
        if tmp is not None:
            tmp.unlink(missing_ok=True)
        raise
    return path


def atomic_write_all(writes: dict[Path, Callable[[Path], object]]) -> list[Path]:
    """Write several files that belong together: all to temporary files first, then every rename
    in one uninterruptible step. A failure or an interrupt before that leaves every target as it
    was, and no temporary file."""
    staged: list[tuple[Path, Path]] = []
    try:
        for path, write in writes.items():
            with uninterrupted():  # created and remembered together, for the clean-up below
                staged.append((_temporary(path), path))
            tmp = staged[-1][0]
            try:
                write(tmp)
                os.chmod(tmp, path.stat().st_mode & 0o777 if path.exists() else 0o666 & ~_umask())
            except OSError as err:
                raise OutputError(path, f"cannot write it ({_reason(err)})") from None
        with uninterrupted():
            for tmp, path in staged:
                try:
                    os.replace(tmp, path)
                except OSError as err:
                    raise OutputError(path, f"cannot write it ({_reason(err)})") from None
    except BaseException:
        for tmp, _ in staged:
            tmp.unlink(missing_ok=True)
        raise
    return [path for _, path in staged]


def _temporary(path: Path) -> Path:
    """An empty temporary file beside `path` (its folder created), named after it but short
    enough for any target name the file system takes."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(
            prefix=f".{path.name[:_TEMP_STEM]}.", suffix=f".partial{path.suffix}", dir=path.parent
        )
    except OSError as err:
        problem = output_problem(path) or f"cannot write it ({_reason(err)})"
        raise OutputError(path, problem) from None
    os.close(fd)
    return Path(name)


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


@contextlib.contextmanager
def new_folder(path: str | os.PathLike) -> Iterator[Path]:
    """The folder `path`, created (with its parents) if missing; if it was missing and the block
    fails or is interrupted, everything it now holds and the folders made for it are removed.

    A folder that existed is left as the block leaves it (its files are each written whole).
    """
    path = Path(path)
    made = []
    probe = path
    while not probe.exists() and probe != probe.parent:
        made.append(probe)
        probe = probe.parent
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(path, output_problem(path, folder=True) or _reason(err)) from None
    try:
        yield path
    except BaseException:
        for folder in made:  # innermost first: only what this block created
            shutil.rmtree(folder, ignore_errors=True)
        raise


# ------------------------------------------------------------------------------- signals
_state = threading.local()
_DEFERRED: list[int] = []  # a signal that arrived inside `uninterrupted`, raised when it ends


@contextlib.contextmanager
def uninterrupted() -> Iterator[None]:
    """A step that must finish once started (renames that belong together): a SIGINT or SIGTERM
    arriving inside it is raised when it ends (with `interrupts_raise` in force)."""
    depth = getattr(_state, "depth", 0)
    _state.depth = depth + 1
    try:
        yield
    finally:
        _state.depth = depth
        if depth == 0 and _DEFERRED:
            raise Interrupted(_DEFERRED.pop())


def _raise(signum: int, frame: object) -> None:
    if getattr(_state, "depth", 0):
        _DEFERRED[:] = [signum]
        return
    raise Interrupted(signum)


#: The signals a command ends on with one line: Ctrl-C and SIGTERM (``kill``, a CI's timeout).
SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def interrupts_raise() -> Iterator[None]:
    """While in force, SIGINT and SIGTERM raise `Interrupted` in the main thread (deferred
    inside `uninterrupted`); the handlers before are restored after. Outside the main thread
    (where Python delivers no signal) it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = {sig: signal.signal(sig, _raise) for sig in SIGNALS}
    try:
        yield
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
