"""Reading a small input file safely: regular files only, and never more than a limit.

A command's inputs are named by the user, and a name can point anywhere: a
FIFO (reading waits for a writer, forever), a device (``/dev/zero`` never
ends, ``/dev/urandom`` neither), a folder, or a file far larger than any
pipeline or calibration could be.  :func:`refuse_special` names such an input
before it is opened; :func:`read_bounded` reads a small input (a pipeline's
TOML, a calibration JSON, a rosbag2 ``metadata.yaml``) with its size checked
first, opening it without blocking and checking again what was opened (a FIFO
swapped in after the check is refused too, never waited on).
"""

from __future__ import annotations

import os
import stat

from wheelcal.io.file_kind import special_kind
from wheelcal.recording import InputError

#: Largest pipeline file, calibration JSON or rosbag2 metadata.yaml read (bytes).
#: The largest wheelcal writes (a pooled sensor calibration with its covariance)
#: is a few hundred kilobytes.
MAX_SMALL_INPUT_BYTES = 64 << 20


class SpecialFileError(InputError):
    """An input that is a FIFO, a device, a socket or a folder, where a file is read."""


class InputTooLargeError(InputError):
    """A small input (pipeline, calibration, metadata) beyond :data:`MAX_SMALL_INPUT_BYTES`."""


def refuse_special(path: str | os.PathLike, what: str = "input") -> None:
    """Raise :class:`SpecialFileError` if ``path`` exists and is not a regular file.

    A missing file is left to the reader, which names it.
    """
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return
    kind = special_kind(mode)
    if kind is not None:
        raise SpecialFileError(path, _special_text(kind, what))


def _special_text(kind: str, what: str) -> str:
    return f"is {kind}, not a file; wheelcal reads its {what} from a regular file (save it first)"


def read_bounded(
    path: str | os.PathLike, what: str = "input", limit_bytes: int = MAX_SMALL_INPUT_BYTES
) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit_bytes`` of them.

    Raises
    ------
    SpecialFileError
        ``path`` is a FIFO, device, socket or folder (checked before and after opening).
    InputTooLargeError
        The file holds more than ``limit_bytes``.
    OSError
        A missing or unreadable file (``FileNotFoundError``, ``PermissionError``…).
    """
    refuse_special(path, what)
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):  # swapped in since the check above
            raise SpecialFileError(path, _special_text(special_kind(info.st_mode), what))
        if info.st_size > limit_bytes:
            raise InputTooLargeError(path, _too_large(info.st_size, limit_bytes, what))
        chunks, total = [], 0
        while piece := os.read(fd, min(1 << 20, limit_bytes + 1 - total)):
            chunks.append(piece)
            total += len(piece)
            if total > limit_bytes:  # grew while being read
                raise InputTooLargeError(path, _too_large(total, limit_bytes, what))
    finally:
        os.close(fd)
    return b"".join(chunks)


def _too_large(size: int, limit: int, what: str) -> str:
    return (
        f"holds {size} bytes, more than the {limit >> 20} MiB any {what} can need; "
        "is it the right file?"
    )
