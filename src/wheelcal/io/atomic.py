"""Atomic file output: a reader never sees a half-written file.

Everything is written to a temporary file in the destination's directory (the
same file system, so the final rename is atomic), flushed and ``fsync``-ed,
then moved over the destination with :func:`os.replace`; the directory is
synced too so the rename survives a power cut.  If anything fails on the way,
the temporary file is removed and the destination is left as it was — never a
partial file.

A destination that exists and is not a regular file — a folder, a device such
as ``/dev/full``, a FIFO, a socket — is never replaced, whatever ``replace``
says (:class:`NotRegularFileError`): renaming over ``/dev/full`` as root
would destroy the device node.

With ``replace=False`` an existing destination is never overwritten: the
finished file is installed with :func:`os.link`, which fails atomically if the
name exists (the check and the install are one system call, so a file created
meanwhile by another process is not lost either), and
:class:`OutputExistsError` names the file.  ``convert``, ``apply`` and
``export`` write this way unless given ``--force``.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
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


class NotRegularFileError(OSError):
    """A destination that exists and is a device, FIFO or socket: never replaced."""


def refuse_non_regular(target: Path, follow: bool = True) -> None:
    """Raise if ``target`` exists and is not a regular file (``follow``: through a link)."""
    try:
        mode = (os.stat if follow else os.lstat)(target).st_mode
    except OSError:
        return
    if stat.S_ISREG(mode) or stat.S_ISLNK(mode):
        return
    if stat.S_ISDIR(mode):  # found now: the final rename would name the temporary file
        raise IsADirectoryError(errno.EISDIR, "is a folder, not a file to write", str(target))
    from wheelcal.io.file_kind import special_kind

    raise NotRegularFileError(
        errno.EEXIST,
        f"is {special_kind(mode)}, not a regular file; wheelcal never writes over it, "
        "even with --force",
        str(target),
    )


def _temporary_beside(path: str | os.PathLike) -> tuple[Path, Path, int, Path]:
    """(target, its directory, fd, path) of a new hidden temporary file next to ``path``."""
    target = Path(path)
    directory = target.parent if str(target.parent) else Path(".")
    refuse_non_regular(target)
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


class OutputExistsError(FileExistsError):
    """An output file that exists and may not be replaced (names the file)."""

    def __init__(self, path: str | os.PathLike) -> None:
        super().__init__(
            errno.EEXIST, "exists; not replaced (give --force to replace it)", str(path)
        )

    def __str__(self) -> str:
        return f"{self.filename}: {self.strerror}"


def refuse_existing(path: str | os.PathLike) -> None:
    """Raise :class:`OutputExistsError` if ``path`` exists (a symbolic link counts too)."""
    if os.path.lexists(path):
        raise OutputExistsError(path)


def _install(tmp: Path, target: Path, replace: bool = True) -> None:
    """Give the finished temporary file the default mode and move it to ``target``.

    ``replace=False`` refuses an existing ``target`` in the same step as the
    install (a hard link fails with EEXIST); where the file system has no hard
    links, the check and the rename are two steps.
    """
    os.chmod(tmp, _default_mode())
    refuse_non_regular(target, follow=False)  # again: it may have appeared meanwhile
    if replace:
        os.replace(tmp, target)
        return
    try:
        os.link(tmp, target)
    except FileExistsError:
        raise OutputExistsError(target) from None
    except OSError as exc:  # no hard links here (FAT, some network file systems)
        if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EXDEV):
            raise
        refuse_existing(target)
        os.replace(tmp, target)
        return
    tmp.unlink()


@contextlib.contextmanager
def atomic_output(
    path: str | os.PathLike, binary: bool = True, durable: bool = True, replace: bool = True
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
    replace:
        ``True`` (default) replaces an existing ``path``; ``False`` refuses it
        before writing and again, atomically, at the install
        (:class:`OutputExistsError`).

    Yields
    ------
    IO
        The open temporary file.  On an exception inside the block it is closed
        and deleted, the exception propagates, and ``path`` is untouched.
    """
    if not replace:
        refuse_existing(path)  # before the work; the install checks again
    target, directory, fd, tmp = _temporary_beside(path)
    with _removed_on_error(tmp):
        mode = "wb" if binary else "w"
        kwargs = {} if binary else {"encoding": "utf-8", "newline": ""}
        with os.fdopen(fd, mode, **kwargs) as stream:
            yield stream
            stream.flush()
            if durable:
                os.fsync(stream.fileno())
        _install(tmp, target, replace)
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


def atomic_write_bytes(
    path: str | os.PathLike, data: bytes, durable: bool = True, replace: bool = True
) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_output`)."""
    with atomic_output(path, binary=True, durable=durable, replace=replace) as stream:
        stream.write(data)


def atomic_write_text(
    path: str | os.PathLike, text: str, durable: bool = True, replace: bool = True
) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`atomic_output`)."""
    with atomic_output(path, binary=False, durable=durable, replace=replace) as stream:
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
        fd, probe = tempfile.mkstemp(prefix=PROBE_PREFIX, dir=folder)
    except OSError as exc:
        raise OutputFolderError(
            f"cannot write in the {what} {folder}: {exc.strerror or exc}"
        ) from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)
    return folder


class StagedOutputs:
    """Files that appear together or not at all: a report set (:func:`staged_outputs`).

    Each file is written completely to its hidden temporary file beside its
    destination first; only when every one is written are they installed,
    by renames (which need no space on a full disk), those given as ``last``
    at the end (the file that marks the set complete).  If anything fails
    before, every temporary file is removed and the destinations are as they
    were: the earlier set, or none.
    """

    def __init__(self, durable: bool = True) -> None:
        self.durable = durable
        self._files: list[tuple[Path, Path]] = []  # (temporary, destination)
        self._moves: list[tuple[Path, Path]] = []  # (old, new): renames at the install

    def write_bytes(self, path: str | os.PathLike, data: bytes) -> None:
        """Stage ``data`` for ``path``."""
        with self._open(path, True) as stream:
            stream.write(data)

    def write_text(self, path: str | os.PathLike, text: str) -> None:
        """Stage ``text`` (UTF-8) for ``path``."""
        with self._open(path, False) as stream:
            stream.write(text)

    @contextlib.contextmanager
    def path(self, path: str | os.PathLike) -> Iterator[Path]:
        """A temporary path for a writer that opens the file itself (Rerun), staged for ``path``."""
        target, _, fd, tmp = _temporary_beside(path)
        os.close(fd)
        with _removed_on_error(tmp):
            yield tmp
        self._files.append((tmp, target))

    def move(self, old: str | os.PathLike, new: str | os.PathLike) -> None:
        """Rename ``old`` to ``new`` at the install (e.g. a file this set makes stale)."""
        self._moves.append((Path(old), Path(new)))

    @contextlib.contextmanager
    def _open(self, path, binary: bool) -> Iterator[IO]:
        target, _, fd, tmp = _temporary_beside(path)
        with _removed_on_error(tmp):
            kwargs = {} if binary else {"encoding": "utf-8", "newline": ""}
            with os.fdopen(fd, "wb" if binary else "w", **kwargs) as stream:
                yield stream
                stream.flush()
                if self.durable:
                    os.fsync(stream.fileno())
        self._files.append((tmp, target))

    def install(self, last: tuple[str | os.PathLike, ...] = ()) -> None:
        """Rename every staged file to its destination, those in ``last`` at the end."""
        final = {Path(p) for p in last}
        ordered = [f for f in self._files if f[1] not in final] + [
            f for f in self._files if f[1] in final
        ]
        for old, new in self._moves:
            with contextlib.suppress(FileNotFoundError):
                os.replace(old, new)
        for tmp, target in ordered:
            _install(tmp, target)
        self._files.clear()
        if self.durable:
            for directory in {target.parent for _, target in ordered}:
                _fsync_directory(directory)

    def discard(self) -> None:
        """Remove every staged temporary file (the destinations are untouched)."""
        for tmp, _ in self._files:
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
        self._files.clear()
        self._moves.clear()


@contextlib.contextmanager
def staged_outputs(
    durable: bool = True, last: tuple[str | os.PathLike, ...] = ()
) -> Iterator[StagedOutputs]:
    """Stage files in the block; install them all when it succeeds, none if it fails."""
    stage = StagedOutputs(durable)
    try:
        yield stage
    except BaseException:
        stage.discard()
        raise
    stage.install(last)


#: The hidden temporary files of :func:`atomic_output` and friends: ``.<name>.<random>.tmp``.
TEMPORARY_PATTERN = r"^\.(?P<name>.+)\.[A-Za-z0-9_]{8}\.tmp$"
#: The write probes of :func:`prepare_output_folder`.
PROBE_PREFIX = ".wheelcal-write-test."


def remove_temporaries(folder: str | os.PathLike, names=None) -> list[Path]:
    """Remove wheelcal's hidden temporary files in ``folder`` (a crashed run's); the removed.

    ``names(name) -> bool`` chooses, by the destination's name, whose temporaries
    go (default: all of wheelcal's).  Only call it when no other wheelcal
    process writes into ``folder``: its temporaries are live.
    """
    import re

    pattern = re.compile(TEMPORARY_PATTERN)
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        match = pattern.match(entry.name)
        probe = entry.name.startswith(PROBE_PREFIX)
        if not (probe or (match and (names is None or names(match.group("name"))))):
            continue
        try:
            if entry.is_file(follow_symlinks=False):
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue
    return removed
