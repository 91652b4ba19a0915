"""Locks that keep two batches writing into one folder from doing the work twice.

One lock file, ``<output>/.wheelcal.lock``, holds a POSIX record lock per
session (one byte at an offset hashed from the session's stem) and one for the
report (byte 0).  A batch takes a session's lock before computing it and checks
again whether the session is up to date: a second batch on the same pipeline
waits for the session the first one is computing, then finds it done and skips
it.  Record locks (``fcntl.lockf``) rather than ``flock`` because they also
work across machines on NFS, which a Dask cluster's shared folder usually is.
The kernel drops a lock when its process dies, so a killed batch never leaves
a session locked.  Where ``fcntl`` does not exist (Windows) the locks do
nothing.

Classic POSIX record locks belong to the *process*: closing any descriptor of
the lock file in that process — another lock's, or any code that opened the
file — silently releases them all, and two threads of one process never
exclude each other.  On Linux the locks are therefore *open file description*
locks (``F_OFD_SETLKW``, Linux ≥ 3.15, also honoured over NFS): each lock
belongs to its own descriptor and lives exactly as long as it, whatever else
the process opens or closes.  Where they are missing, the process keeps one
descriptor per lock file for as long as any of its locks is held (never
closing it under a held lock) and a thread lock per byte, so the guarantee is
the same within what POSIX locks allow.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import struct
import threading
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX
    fcntl = None

#: The lock file in every batch output folder.
LOCK_FILE = ".wheelcal.lock"
_REPORT_OFFSET = 0


def _offset(stem: str) -> int:
    digest = hashlib.sha256(stem.encode("utf-8", "surrogateescape")).digest()
    return 1 + int.from_bytes(digest[:4], "big") % (2**31 - 2)


#: Linux's open file description locks (Python exposes the constants on Linux only).
_OFD_SETLKW = getattr(fcntl, "F_OFD_SETLKW", None) if fcntl is not None else None


def _flock(kind: int, offset: int) -> bytes:
    """A ``struct flock`` for one byte at ``offset`` (l_type, l_whence, l_start, l_len, l_pid).

    Layout of Linux's ``struct flock`` on every 64-bit ABI: two shorts, two
    off_t and an int (pid 0: required for OFD locks), padded to 32 bytes.
    """
    return struct.pack("hhqqi4x", kind, os.SEEK_SET, offset, 1, 0)


@contextlib.contextmanager
def _ofd_locked(path: Path, offset: int) -> Iterator[None]:
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    try:
        fcntl.fcntl(fd, _OFD_SETLKW, _flock(fcntl.F_WRLCK, offset))
        yield  # closing fd (below) releases the lock; nothing else can
    finally:
        os.close(fd)


class _SharedDescriptors:
    """One descriptor per lock file for the whole process (POSIX record-lock fallback)."""

    def __init__(self) -> None:
        self._guard = threading.Lock()
        self._files: dict[str, list[int]] = {}  # real path -> [fd, users]
        self._bytes: dict[tuple[str, int], threading.Lock] = {}

    @contextlib.contextmanager
    def locked(self, path: Path, offset: int) -> Iterator[None]:
        key = os.path.realpath(path)
        with self._guard:
            byte = self._bytes.setdefault((key, offset), threading.Lock())
        with byte:  # threads of this process exclude each other here
            with self._guard:
                entry = self._files.get(key)
                if entry is None:
                    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
                    entry = self._files[key] = [fd, 0]
                entry[1] += 1
            try:
                fcntl.lockf(entry[0], fcntl.LOCK_EX, 1, offset)
                try:
                    yield
                finally:
                    fcntl.lockf(entry[0], fcntl.LOCK_UN, 1, offset)
            finally:
                with self._guard:
                    entry[1] -= 1
                    if entry[1] == 0:  # no lock of this process on the file any more
                        del self._files[key]
                        os.close(entry[0])


_SHARED = _SharedDescriptors()


@contextlib.contextmanager
def _locked(out_dir: str | os.PathLike, offset: int) -> Iterator[None]:
    if fcntl is None:  # pragma: no cover
        yield
        return
    path = Path(out_dir) / LOCK_FILE
    if _OFD_SETLKW is not None:
        with _ofd_locked(path, offset):
            yield
    else:  # pragma: no cover - not Linux
        with _SHARED.locked(path, offset):
            yield


def session_lock(out_dir: str | os.PathLike, stem: str):
    """Hold the lock of one session's outputs (blocks while another batch holds it)."""
    return _locked(out_dir, _offset(stem))


def report_lock(out_dir: str | os.PathLike):
    """Hold the lock of the folder's report files."""
    return _locked(out_dir, _REPORT_OFFSET)


# --- one pipeline per folder ----------------------------------------------------------

#: Bytes of the lock file past the sessions' (which lie below 2**31): a mutex for
#: entering, the folder's "in use" byte, and one byte per pipeline identity above.
_ENTRY_OFFSET = 1 << 31
_IN_USE_OFFSET = _ENTRY_OFFSET + 1
_IDENTITY_BASE = _ENTRY_OFFSET + 2


class FolderInUseError(RuntimeError):
    """Another batch, on a different pipeline, writes into the output folder now."""


def _identity_offset(identity: str) -> int:
    digest = hashlib.sha256(identity.encode()).digest()
    return _IDENTITY_BASE + int.from_bytes(digest[:4], "big") % (1 << 30)


def _held_by_others(fd: int, offset: int) -> bool:
    """Whether another open file description holds a lock on the byte at ``offset``."""
    probe = fcntl.fcntl(fd, fcntl.F_OFD_GETLK, _flock(fcntl.F_WRLCK, offset))
    return struct.unpack("hhqqi4x", probe)[0] != fcntl.F_UNLCK


@contextlib.contextmanager
def pipeline_lock(out_dir: str | os.PathLike, identity: str, who: str) -> Iterator[bool]:
    """Hold the output folder for one pipeline: a second, *different* one is refused.

    ``identity`` says what the pipeline computes (two runs of the same pipeline
    share it and may run at once, as before: the session locks keep them from
    computing a session twice).  Yields whether this batch is the folder's only
    user (then no other batch's temporary files can be live in it).  ``who``
    (the pipeline's name and file) is left as the lock file's text, for the
    refusal another batch may have to give.

    Raises
    ------
    FolderInUseError
        Another batch with a different identity holds the folder.
    """
    if fcntl is None or _OFD_SETLKW is None:  # pragma: no cover - not Linux: no check
        yield False
        return
    folder = Path(out_dir)
    fd = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    try:
        fcntl.fcntl(fd, _OFD_SETLKW, _flock(fcntl.F_WRLCK, _ENTRY_OFFSET))  # one enters at a time
        try:
            own = _identity_offset(identity)
            in_use = _held_by_others(fd, _IN_USE_OFFSET)
            if in_use and not _held_by_others(fd, own):
                raise FolderInUseError(
                    f"the output folder {folder} is in use by another batch with a different "
                    f"pipeline ({_user(folder)}); wait for it to finish, or give this one "
                    "another output folder (--out): two pipelines in one folder would pool "
                    "each other's sessions"
                )
            fcntl.fcntl(fd, _OFD_SETLKW, _flock(fcntl.F_RDLCK, _IN_USE_OFFSET))
            fcntl.fcntl(fd, _OFD_SETLKW, _flock(fcntl.F_RDLCK, own))
            if not in_use:
                _leave_user(fd, who)
        finally:
            fcntl.fcntl(fd, _OFD_SETLKW, _flock(fcntl.F_UNLCK, _ENTRY_OFFSET))
        yield not in_use
    finally:
        os.close(fd)  # releases the folder's locks with it


def _user(folder: Path) -> str:
    """Who holds the folder, as the lock file's text says (informative only)."""
    try:
        text = (folder / LOCK_FILE).read_bytes()[:400].decode("utf-8", "replace")
    except OSError:
        return "unknown"
    return text.strip().strip("\x00") or "unknown"


def _leave_user(fd: int, who: str) -> None:
    """Say who uses the folder in the lock file's bytes (the locks do not care about them)."""
    text = f"{who}\n".encode("utf-8", "replace")
    with contextlib.suppress(OSError):
        if os.pread(fd, len(text) + 1, 0) != text:
            os.ftruncate(fd, 0)
            os.pwrite(fd, text, 0)
