"""Decompression bombs and a memory-limited reader, shared by the hostile-file tests.

The readers are run in a subprocess whose data segment is limited to
``LIMIT_BYTES``, so a regression fails the test (``MemoryError``) instead of
exhausting the machine.
"""

import os
import resource
import subprocess
import sys

MIB = 1 << 20
LIMIT_BYTES = 1536 * MIB  # the reader's process may use this much data at most

_READ_SCRIPT = """
import sys
from wheelcal.io import InputError, read_recording
try:
    read_recording(sys.argv[1])
except InputError as exc:
    print(type(exc).__name__, exc)
"""


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_DATA, (LIMIT_BYTES, LIMIT_BYTES))


def read_limited(path) -> str:
    """``read_recording(path)`` in a memory-limited subprocess: what it printed."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    out = subprocess.run(
        [sys.executable, "-c", _READ_SCRIPT, str(path)],
        capture_output=True,
        text=True,
        preexec_fn=_limit_memory,
        env=env,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout


def bz2_zeros(mib: int) -> bytes:
    """``mib`` MiB of zeros as concatenated bz2 streams of 1 MiB each (≈ 40 bytes apiece)."""
    import bz2

    return bz2.compress(bytes(MIB)) * mib


def lz4_zeros(size_bytes: int) -> bytes:
    """``size_bytes`` of zeros as one LZ4 frame."""
    import lz4.frame

    comp = lz4.frame.LZ4FrameCompressor()
    block = bytes(MIB)
    parts = [comp.begin()] + [comp.compress(block) for _ in range(size_bytes // MIB)]
    return b"".join(parts) + comp.flush()


def zstd_zeros(size_bytes: int, content_size: bool) -> bytes:
    """``size_bytes`` of zeros as one zstd frame, its size declared or not."""
    import zstandard

    comp = zstandard.ZstdCompressor(write_content_size=content_size).compressobj(size=size_bytes)
    block = bytes(MIB)
    return b"".join(comp.compress(block) for _ in range(size_bytes // MIB)) + comp.flush()


def mcap_record(op: int, content: bytes) -> bytes:
    """One raw MCAP record: opcode, 8-byte length, content."""
    return bytes([op]) + len(content).to_bytes(8, "little") + content


def mcap_string(text: str) -> bytes:
    """An MCAP string field: 4-byte length, UTF-8 bytes."""
    raw = text.encode()
    return len(raw).to_bytes(4, "little") + raw
