"""Atomic file output: a reader never sees a half-written file.

Everything is written to a temporary file in the destination's directory (the
same file system, so the final rename is atomic), flushed and ``fsync``-ed,
then moved over the destination with :func:`os.replace`; the directory is
synced too so the rename survives a power cut.  If anything fails on the way,
the temporary file is removed and the destination is left as it was — never a
partial file.
"""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO


def _default_mode() -> int:
    """The permissions a plain ``open(path, "w")`` would give (0o666 minus the umask)."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


def _fsync_directory(directory: Path) -> None:
    """Make a rename in ``directory`` durable (best effort: not every OS allows it)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _temporary_beside(path: str | os.PathLike) -> tuple[Path, Path, int, Path]:
    """(target, its directory, fd, path) of a new hidden temporary file next to ``path``."""
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    if target.is_dir():  # found now: the final rename would name the temporary file
        raise IsADirectoryError(errno.EISDIR, "is a folder, not a file to write", str(target))
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:  # name the file the user asked for, not our hidden temporary one
        raise OSError(exc.errno, exc.strerror, str(target)) from None
    return target, directory, fd, Path(tmp_name)


@contextlib.contextmanager
def _removed_on_error(tmp: Path) -> Iterator[None]:
    """Delete the temporary file ``tmp`` if the block raises (and re-raise)."""
    try:
        yield
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def _install(tmp: Path, target: Path) -> None:
    """Give the finished temporary file the default mode and rename it over ``target``."""
    os.chmod(tmp, _default_mode())
    os.replace(tmp, target)


@contextlib.contextmanager
def atomic_output(
    path: str | os.PathLike, binary: bool = True, durable: bool = True
) -> Iterator[IO]:
    """Open a temporary file that replaces ``path`` when the ``with`` block succeeds.

    Parameters
    ----------
    path:
        Destination.  Its directory must exist.
    binary:
        ``True`` for a binary stream, ``False`` for UTF-8 text.
    durable:
        ``True`` (default) also ``fsync``-s the file and its directory, so the
        new file survives a power cut.  ``False`` keeps the atomicity (a reader
        or a crashed process never sees a partial file) without the syncs; the
        batch runner uses it per session and syncs once at the end, because on
        a journalling file system each fsync flushes everything else pending.

    Yields
    ------
    IO
        The open temporary file.  On an exception inside the block it is closed
        and deleted, the exception propagates, and ``path`` is untouched.
    """
    target, directory, fd, tmp = _temporary_beside(path)
    with _removed_on_error(tmp):
        mode = "wb" if binary else "w"
        kwargs = {} if binary else {"encoding": "utf-8", "newline": ""}
        with os.fdopen(fd, mode, **kwargs) as stream:
            yield stream
            stream.flush()
            if durable:
                os.fsync(stream.fileno())
        _install(tmp, target)
    if durable:
        _fsync_directory(directory)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, durable: bool = True) -> Iterator[Path]:
    """A temporary file's path that replaces ``path`` when the ``with`` block succeeds.

    For writers that open the file themselves (Rerun's file sink writes from
    its own thread): the block writes the temporary file and has closed it when
    it ends.  Then, as in :func:`atomic_output`, it is ``fsync``-ed (with
    ``durable``) and renamed over ``path``; on an exception it is deleted and
    ``path`` is untouched.
    """
    target, directory, fd, tmp = _temporary_beside(path)
    os.close(fd)
    with _removed_on_error(tmp):
        yield tmp
        if durable:
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        _install(tmp, target)
    if durable:
        _fsync_directory(directory)


def atomic_write_bytes(path: str | os.PathLike, data: bytes, durable: bool = True) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_output`)."""
    with atomic_output(path, binary=True, durable=durable) as stream:
        stream.write(data)


def atomic_write_text(path: str | os.PathLike, text: str, durable: bool = True) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_output`)."""
    with atomic_output(path, binary=False, durable=durable) as stream:
        stream.write(text)


class OutputFolderError(ValueError):
    """An output folder that cannot be created or written (names the folder)."""


def prepare_output_folder(path: str | os.PathLike, what: str = "output folder") -> Path:
    """Create ``path`` if needed and prove it writable, before any work is done.

    A read-only folder found only after every session was computed wastes the
    run, and its error would name a hidden temporary file; this names the
    folder instead.

    Raises
    ------
    OutputFolderError
        For a dangling symbolic link, a path that is a file, a folder that
        cannot be created or one that cannot be written.
    """
    folder = Path(path)
    if folder.is_symlink() and not folder.exists():
        raise OutputFolderError(
            f"{what} {folder} is a symbolic link to {os.readlink(folder)}, which does not exist"
        )
    if folder.exists() and not folder.is_dir():
        raise OutputFolderError(f"{what} {folder} exists and is not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputFolderError(
            f"cannot create the {what} {folder}: {exc.strerror or exc}"
        ) from None
    try:
        fd, probe = tempfile.mkstemp(prefix=".wheelcal-write-test.", dir=folder)
    except OSError as exc:
        raise OutputFolderError(
            f"cannot write in the {what} {folder}: {exc.strerror or exc}"
        ) from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)
    return folder
