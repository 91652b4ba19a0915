"""Errors raised by the file readers and writers.

Every message starts with the file it is about and says what is wrong in
words a user can act on (CONTRACT: "Errors name the file and what is wrong").
All are :class:`~wheelcal.recording.RecordingError` (a ``ValueError``), so a
caller that handles bad recordings handles bad files too.
"""

from __future__ import annotations

from wheelcal.recording import InputError, RecordingError, SampleError

__all__ = [
    "CorruptFileError",
    "InputError",
    "MetadataError",
    "NotMcapError",
    "RecordingError",
    "SampleError",
    "TopicError",
    "describe_error",
]


class NotMcapError(InputError):
    """The file is empty or does not start with the MCAP magic bytes."""


class CorruptFileError(InputError):
    """The file is truncated, or a CRC or record structure does not check out."""


class TopicError(InputError):
    """No accelerometer topic, several candidates and no choice, or an unknown topic."""


class MetadataError(InputError):
    """The recording's ``wheelcal.session`` metadata is missing, unparsable or out of range."""


def describe_error(exc: BaseException) -> str:
    """An error in words: ``path: Permission denied`` rather than ``[Errno 13] …: 'path'``."""
    if isinstance(exc, OSError) and exc.strerror:
        if exc.filename is None:
            return exc.strerror
        where = f"{exc.filename} -> {exc.filename2}" if exc.filename2 else f"{exc.filename}"
        return f"{where}: {exc.strerror}"
    return str(exc)
