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
"""

from __future__ import annotations

import contextlib
import hashlib
import os
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


@contextlib.contextmanager
def _locked(out_dir: str | os.PathLike, offset: int) -> Iterator[None]:
    if fcntl is None:  # pragma: no cover
        yield
        return
    fd = os.open(Path(out_dir) / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        fcntl.lockf(fd, fcntl.LOCK_EX, 1, offset)
        try:
            yield
        finally:
            fcntl.lockf(fd, fcntl.LOCK_UN, 1, offset)
    finally:
        os.close(fd)


def session_lock(out_dir: str | os.PathLike, stem: str):
    """Hold the lock of one session's outputs (blocks while another batch holds it)."""
    return _locked(out_dir, _offset(stem))


def report_lock(out_dir: str | os.PathLike):
    """Hold the lock of the folder's report files."""
    return _locked(out_dir, _REPORT_OFFSET)
