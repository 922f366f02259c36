"""Output files: whole or absent, inside their folder, with the usual permissions.

Every result file (JSON, CSV, PNG, GIF) is written to a temporary file with a unique name in
the same folder and renamed into place, so a reader never sees half a file and two runs writing
into one folder cannot trip over each other's temporary files. Temporary files are created with
mode 0666 filtered by the umask, so results get the usual permissions (0644 under the default
umask). Folders are checked before any work (:func:`check_directory`), and a problem's folder
is locked while its files are replaced (:func:`locked`, advisory, where the system has it).
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

OUTPUT_FILES = (
    "solution.json", "trajectory.csv", "tracking.csv", "third_link.png", "arm.png",
    "torques.png", "gamma.png", "tracking.png", "arm.gif",
)  # fmt: skip
"""Every file a run may write into a problem's folder."""


_LIVE: set[Path] = set()
"""Temporary files being written (removed by :func:`remove_temporaries` on a hard stop)."""


class OutputError(OSError):
    """An output folder that cannot be used (a file, a symbolic link, not writable)."""


def _temporary(path: Path) -> Path:
    """A new empty file beside ``path`` with a unique name and the same suffix."""
    while True:
        tmp = path.with_name(f".{path.stem}.{secrets.token_hex(6)}.tmp{path.suffix}")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            _LIVE.add(tmp)
            return tmp
        except FileExistsError:  # pragma: no cover - 48 random bits
            continue


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """A temporary path to write ``path`` through; renamed into place if the block succeeds.

    For writers that want a file name (matplotlib, Pillow). On any exception, including
    KeyboardInterrupt, the temporary file is removed and ``path`` is left as it was.
    """
    path = Path(path)
    tmp = _temporary(path)
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    finally:
        _LIVE.discard(tmp)


def remove_temporaries() -> None:
    """Remove the temporary files still being written (before a hard exit)."""
    for tmp in list(_LIVE):
        tmp.unlink(missing_ok=True)


def atomic_write(path: str | Path, write, binary: bool = False) -> None:
    """Write a file through :func:`atomic_path`: ``write(handle)`` fills it.

    Parameters
    ----------
    path : str or Path
        The file.
    write : callable
        Called with an open handle (text, UTF-8, or binary with ``binary=True``).
    binary : bool
        Open the handle in binary mode.
    """
    with atomic_path(path) as tmp:
        if binary:
            with open(tmp, "wb") as handle:
                write(handle)
        else:
            with open(tmp, "w", encoding="utf-8", newline="") as handle:
                write(handle)


def _probe(directory: Path) -> None:
    """Create and remove a file in ``directory``: the only check of writability root obeys."""
    try:
        probe = _temporary(directory / "probe")
        probe.unlink()
        _LIVE.discard(probe)
    except OSError as err:
        raise OutputError(f"{directory}: cannot write there ({err.strerror or err})") from None


def check_directory(path: str | Path) -> None:
    """Refuse a folder results cannot go to, before any work is done.

    An existing path must be a writable folder (not a symbolic link when it is a problem's
    folder: see :func:`check_problem_directory`); a missing one must have a folder as its
    nearest existing parent. Nothing is created.

    Raises
    ------
    OutputError
        Saying what is wrong with which path.
    """
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            raise OutputError(f"{path}: exists and is not a directory")
        _probe(path)
        return
    parent = path.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise OutputError(f"{path}: cannot be created, {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{path}: cannot be created in {parent} (not writable)")


def check_problem_directory(path: str | Path) -> None:
    """:func:`check_directory` for a problem's folder, which must not be a symbolic link
    (results stay inside the output folder)."""
    path = Path(path)
    if path.is_symlink():
        raise OutputError(f"{path}: is a symbolic link; results stay inside the output folder")
    check_directory(path)


def make_directory(path: str | Path) -> Path:
    """Create a folder (and its parents) and check it can be written to."""
    path = Path(path)
    if not path.is_dir():
        check_directory(path)  # says which file is in the way
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"{path}: cannot create it ({err.strerror or err})") from None
    _probe(path)
    return path


def clear(directory: str | Path, names=OUTPUT_FILES) -> None:
    """Remove earlier results from a problem's folder (other files are left alone)."""
    for name in names:
        (Path(directory) / name).unlink(missing_ok=True)


@contextmanager
def locked(directory: str | Path) -> Iterator[None]:
    """Hold an advisory lock on a folder while its results are replaced (POSIX; else no-op)."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    fd = os.open(directory, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # releases the lock


__all__ = [
    "OUTPUT_FILES",
    "OutputError",
    "atomic_path",
    "atomic_write",
    "check_directory",
    "check_problem_directory",
    "clear",
    "locked",
    "make_directory",
    "remove_temporaries",
]
