"""One ``.rrd`` file from one private Rerun stream, written atomically.

Every file gets its own :class:`rerun.RecordingStream` (fresh random
``recording_id``: loading two files, or a file and its rewrite, into one
viewer never merges them), connected to a :class:`rerun.FileSink` on a hidden
temporary file next to the destination.  Nothing touches Rerun's global or
thread-default recording, so sessions can be written concurrently.

While the block runs, Rerun's *strict mode* is switched on for this thread
only: by default Rerun turns a bad call (wrong shape, wrong type) into a
warning and carries on, which would leave a silently incomplete file.  In
strict mode it raises instead.  (Only partly: rerun-sdk 0.41's
``RecordingStream.log`` and ``send_columns`` pass ``strict=None`` down, so a
problem found inside them is still a warning, and that warning can leave the
thread's strict mode off for the rest of the block.  Whatever happens to
strict mode, an exception raised in the block aborts the file.)

The file sink encodes on its own thread while the block is still logging, and
writes straight to the file: no copy of the whole file in memory (an
in-memory ``binary_stream`` read back into Python bytes cost ≈ 2 ms more per
90 s session, ``benchmarks/bench_rrd.py``).  Rerun reports a failed write on
that thread only as a log line, so the file is checked when the stream is
closed: it must end with the RRD stream footer (:data:`_FOOTER_MAGIC`), which
Rerun writes last.  Then :func:`wheelcal.io.atomic.atomic_path` fsyncs it and
renames it over the destination, so an error at any point leaves no file, or
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

from wheelcal.io import atomic_path

#: The last bytes of a complete RRD stream (rerun-sdk 0.41): ``RRF2`` ``FOOT`` and
#: a 4-byte version follow the footer, which the sink writes when it closes.
_FOOTER_MAGIC = b"RRF2FOOT"


class RrdWriteError(OSError):
    """A ``.rrd`` file could not be produced (the message names the file and why)."""


def _check_complete(tmp: Path, target: Path) -> None:
    """Raise :class:`RrdWriteError` unless ``tmp`` ends with a complete RRD footer."""
    try:
        with open(tmp, "rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            f.seek(max(0, size - 12))
            tail = f.read()
    except OSError as exc:
        raise RrdWriteError(f"{target}: cannot read back the written file: {exc}") from None
    if len(tail) < 12 or tail[:8] != _FOOTER_MAGIC:
        raise RrdWriteError(
            f"{target}: Rerun did not finish writing the file ({size} bytes, no stream "
            "footer); see Rerun's log for why (disk full?)"
        )


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
        Passed to :func:`wheelcal.io.atomic.atomic_path` (fsync or not).

    Yields
    ------
    rerun.RecordingStream
        Log to it (``stream.log``, ``stream.send_columns``,
        ``stream.send_blueprint``), never to the global ``rr.*`` functions.

    Raises
    ------
    RrdWriteError
        If Rerun logging is disabled (environment ``RERUN=off``) or the file
        was not written completely.  Exceptions raised inside the block
        propagate unchanged; in either case no file is written.
    """
    target = Path(path)
    stream = rr.RecordingStream(application_id, recording_id=uuid.uuid4(), send_properties=True)
    if not stream.is_enabled():
        raise RrdWriteError(
            f"{target}: Rerun logging is disabled (environment variable RERUN=off); "
            "unset it to write .rrd files"
        )
    with atomic_path(target, durable=durable) as tmp:
        failure: BaseException | None = None
        try:
            stream.set_sinks(rr.FileSink(tmp))
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
            stream.flush()
        finally:
            stream.disconnect()  # closes the sink: its thread writes the footer and ends
        _check_complete(tmp, target)
