"""What a path is when it is not a regular file (a recording must be one)."""

from __future__ import annotations

import os
import stat


def special_kind(mode: int) -> str | None:
    """``"a folder"``, ``"a FIFO (named pipe)"``, … for an ``st_mode``; None for a regular file."""
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def special_file_kind(path: str | os.PathLike) -> str | None:
    """:func:`special_kind` of an existing ``path``; None for a regular or missing file."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return None
    return special_kind(mode)
