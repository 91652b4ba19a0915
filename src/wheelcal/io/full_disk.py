"""Whether a failed write means the disk is full (no space, a quota, a file-size limit).

A full disk fails every session after it, so the batch stops at the first; a
single session says so in its error.  :func:`disk_full` tells such a failure
from a bad session.
"""

from __future__ import annotations

import errno
import os
import tempfile

#: The errors of a full disk (no space, a quota, a file-size limit).
FULL_DISK_ERRNOS = frozenset(
    e for e in (errno.ENOSPC, getattr(errno, "EDQUOT", None), errno.EFBIG) if e is not None
)
#: A write of this size must succeed in the output folder, or its disk counts as full.
_PROBE_BYTES = 1 << 20


def disk_full(exc: BaseException, folder: str | os.PathLike) -> bool:
    """Whether a failed write means the disk of ``folder`` is full.

    An ``ENOSPC``/``EDQUOT``/``EFBIG`` error says so itself; any other failure
    to write (Rerun's writer thread reports only that it stopped) is judged by
    trying to write :data:`_PROBE_BYTES` there.
    """
    seen = exc
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno in FULL_DISK_ERRNOS:
            return True
        seen = seen.__cause__ or seen.__context__
    try:
        with tempfile.TemporaryFile(dir=folder) as probe:
            probe.write(bytes(_PROBE_BYTES))
            probe.flush()
            os.fsync(probe.fileno())
    except OSError as probe_error:
        return probe_error.errno in FULL_DISK_ERRNOS
    return False
