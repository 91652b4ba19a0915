"""One ``.rrd`` file from one private Rerun stream, written atomically.

Every file gets its own :class:`rerun.RecordingStream` (fresh random
``recording_id``: loading two files, or a file and its rewrite, into one
viewer never merges them), connected to an in-memory
:meth:`~rerun.RecordingStream.binary_stream` sink.  Nothing touches Rerun's
global or thread-default recording, so sessions can be written concurrently.

While the block runs, Rerun's *strict mode* is switched on for this thread
only: by default Rerun turns a bad call (wrong shape, wrong type) into a
warning and carries on, which would leave a silently incomplete file.  In
strict mode it raises instead.  (Only partly: rerun-sdk 0.41's
``RecordingStream.log`` and ``send_columns`` pass ``strict=None`` down, so a
problem found inside them is still a warning, and that warning can leave the
thread's strict mode off for the rest of the block.  Whatever happens to
strict mode, an exception raised in the block aborts the file.)  When the
block ends without an exception the encoded bytes (RRD with footer, plus the
blueprint store) are written with :func:`wheelcal.io.atomic.atomic_write_bytes`
— temporary file, fsync, rename — so an error at any point leaves no file, or
the previous file intact.
"""

from __future__ import annotations

import contextlib
import os
import uuid
from collections.abc import Iterator
from pathlib import Path

import rerun as rr
from rerun.error_utils import catch_and_log_exceptions

from wheelcal.io.atomic import atomic_write_bytes


class RrdWriteError(OSError):
    """A ``.rrd`` file could not be produced (the message names the file and why)."""


@contextlib.contextmanager
def rrd_file(
    path: str | os.PathLike, application_id: str, recording_name: str, durable: bool = True
) -> Iterator[rr.RecordingStream]:
    """A fresh recording stream whose contents become ``path`` when the block succeeds.

    Parameters
    ----------
    path:
        Destination ``.rrd``; its directory must exist.
    application_id:
        Rerun application id.  The viewer keeps one active blueprint per
        application id, so files with different layouts use different ids.
    recording_name:
        Human-readable name shown in the viewer's recording list.
    durable:
        Passed to :func:`wheelcal.io.atomic.atomic_output` (fsync or not).

    Yields
    ------
    rerun.RecordingStream
        Log to it (``stream.log``, ``stream.send_columns``,
        ``stream.send_blueprint``), never to the global ``rr.*`` functions.

    Raises
    ------
    RrdWriteError
        If Rerun logging is disabled (environment ``RERUN=off``) or produced
        no data.  Exceptions raised inside the block propagate unchanged; in
        either case no file is written.
    """
    target = Path(path)
    stream = rr.RecordingStream(application_id, recording_id=uuid.uuid4(), send_properties=True)
    if not stream.is_enabled():
        raise RrdWriteError(
            f"{target}: Rerun logging is disabled (environment variable RERUN=off); "
            "unset it to write .rrd files"
        )
    sink = stream.binary_stream()
    failure: BaseException | None = None
    try:
        with catch_and_log_exceptions(context="wheelcal .rrd writer", strict=True):
            try:
                stream.send_recording_name(recording_name)
                yield stream
            except BaseException as exc:
                failure = exc
                raise
        if failure is not None:
            # Swallowed as a warning: a Rerun warning inside the block can leave
            # strict mode off (see the module docstring).  It still aborts the file.
            raise failure
        data = sink.read(flush=True)
    finally:
        stream.disconnect()
    if not data:
        raise RrdWriteError(f"{target}: Rerun produced no data to write")
    atomic_write_bytes(target, data, durable=durable)
