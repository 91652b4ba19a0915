"""Decompression with limits: compressed data never expand beyond what a reader accepts.

Every reader of a compressed container uses this module — MCAP chunks (zstd,
lz4), ROS 1 bag chunks (bz2, lz4) and rosbag2 messages compressed one by one
(zstd) — so a "decompression bomb" (a few kilobytes that unpack to gigabytes)
is refused the same way, with the same words, whatever the container:

* a **ratio cap**: at most :data:`MAX_RATIO` × the compressed size (plus
  :data:`SLACK_BYTES`, so tiny records pass) — real sensor data reach ~40×
  (zstd, a sensor exactly at rest), a block of zeros thousands;
* an **absolute cap**: :data:`MAX_BYTES` per chunk (writers use 1–8 MiB);
* the **declared size** is judged *before* anything is allocated, and the data
  are decompressed in pieces of at most :data:`PIECE_BYTES` into a buffer of
  that size, so data that expand beyond their claim (or a frame that states no
  size, or a false one) fail after at most the claim.

:func:`decompress_sized` serves a chunk that states its uncompressed size (MCAP,
ROS 1); :func:`decompress_unsized` a piece that does not (a rosbag2 message),
against a budget its caller keeps for a block of messages.
"""

from __future__ import annotations

from wheelcal.io.errors import CorruptFileError

#: Largest plausible ratio of a chunk's uncompressed size to its compressed size.
#: ROS 2 Imu and AccelBatch chunks reach ~40× with zstd (a sensor at rest, exactly
#: constant samples; noisy floats ~11×), ~19× with lz4 and ~84× with bz2 (ROS 1
#: Imu messages exactly at rest, zero gyro; rosbags' writer): 200× leaves a margin,
#: while a zero-filled "decompression bomb" claims thousands.
MAX_RATIO = 200
#: Lets tiny chunks (headers, a few records) pass the ratio cap.
SLACK_BYTES = 1 << 16
#: Absolute cap on one chunk's uncompressed size (writers use 1–8 MiB chunks).
MAX_BYTES = 512 << 20
#: Decompress in pieces of at most this size.
PIECE_BYTES = 4 << 20
#: The compressions the readers meet ("" = stored as is).
COMPRESSIONS = ("", "zstd", "lz4", "bz2")


def limit_bytes(compressed_bytes: int) -> int:
    """The most that ``compressed_bytes`` of data may decompress to."""
    return min(MAX_RATIO * compressed_bytes + SLACK_BYTES, MAX_BYTES)


def _caps(unit: str) -> str:
    return (
        f"wheelcal accepts at most {MAX_RATIO}× and {MAX_BYTES >> 20} MiB per {unit} "
        "(a damaged file or a decompression bomb)"
    )


def decompress_sized(path: str, compression: str, data, size: int, where: str, unit: str = "chunk"):
    """``data`` decompressed into one buffer of the claimed ``size`` (bytes or a view).

    The claim is judged before anything is allocated; the data are then
    decompressed in bounded pieces, so data that would expand beyond the claim
    fail after at most ``size`` bytes.

    Raises
    ------
    CorruptFileError
        Naming ``path``, ``where`` and what is wrong: an unsupported compression,
        a claim beyond the caps, damaged data, or data that decompress to more
        or fewer bytes than claimed.
    """
    if compression == "":
        if len(data) != size:
            raise CorruptFileError(
                path, f"{where}: holds {len(data)} bytes of records, the {unit} says {size}"
            )
        return data
    _check_compression(path, compression, where)
    limit = limit_bytes(len(data))
    if size > limit:
        raise CorruptFileError(
            path,
            f"{where}: claims {size} bytes uncompressed from {len(data)} compressed bytes "
            f"(ratio {size / max(len(data), 1):.0f}); {_caps(unit)}",
        )
    out = bytearray(size)
    pos, extra = _stream_into(path, compression, data, out, where)
    if extra:
        raise CorruptFileError(
            path, f"{where}: decompresses to more than the {size} bytes the {unit} says"
        )
    if pos != size:
        raise CorruptFileError(
            path, f"{where}: decompressed to {pos} bytes, the {unit} says {size}"
        )
    return out


def decompress_unsized(
    path: str,
    compression: str,
    data,
    budget: int,
    where: str,
    unit: str = "block of messages",
    zstd_decompressor=None,
) -> bytes:
    """``data`` decompressed, refused as soon as it exceeds ``budget`` bytes.

    For pieces that state no uncompressed size (a rosbag2 message); a zstd
    frame that does state one is judged by it before anything is allocated
    (then decompressed in one call, into exactly that size).  The caller keeps
    ``budget`` for a block of pieces (:func:`limit_bytes` of their compressed
    total, less what was used).  ``zstd_decompressor``: one to reuse (a
    ``zstandard.ZstdDecompressor``; making one per message costs more than the
    message).
    """
    _check_compression(path, compression, where)
    declared = -1
    if compression == "zstd":
        import zstandard

        try:
            declared = zstandard.frame_content_size(bytes(data[:18]))
        except zstandard.ZstdError:
            declared = -1  # not a frame header: the decompressor says what is wrong
        if declared > budget:
            raise CorruptFileError(
                path,
                f"{where}: a zstd frame of {len(data)} bytes declares {declared} bytes "
                f"uncompressed, beyond the {budget} left for its {unit}; {_caps(unit)}",
            )
    try:
        if declared >= 0:
            return (zstd_decompressor or zstandard.ZstdDecompressor()).decompress(bytes(data))
        pieces, total = [], 0
        for piece in _pieces(compression, data):
            total += len(piece)
            if total > budget:
                raise CorruptFileError(
                    path,
                    f"{where}: {len(data)} compressed bytes decompress to more than the "
                    f"{budget} bytes left for its {unit}; {_caps(unit)}",
                )
            pieces.append(piece)
    except CorruptFileError:
        raise
    except Exception as exc:  # zstandard.ZstdError, lz4's RuntimeError, bz2's OSError
        raise CorruptFileError(
            path, f"{where}: {compression} data is damaged ({type(exc).__name__}: {exc})"
        ) from None
    return b"".join(pieces)


def _pieces(compression: str, data):
    """The decompressed data in pieces of at most :data:`PIECE_BYTES` (a generator)."""
    if compression == "zstd":
        import zstandard

        reader = zstandard.ZstdDecompressor().stream_reader(bytes(data), read_across_frames=True)
        while piece := reader.read(PIECE_BYTES):
            yield piece
        return
    if compression == "lz4":
        import lz4.frame

        make = lz4.frame.LZ4FrameDecompressor
    else:
        import bz2

        make = bz2.BZ2Decompressor
    decompressor, source = make(), bytes(data)
    while True:
        piece = decompressor.decompress(source, max_length=PIECE_BYTES)
        source = b""
        if piece:
            yield piece
        if decompressor.eof:
            if not decompressor.unused_data:
                return
            decompressor, source = make(), decompressor.unused_data  # concatenated frames
        elif not piece and decompressor.needs_input:
            return


def _check_compression(path: str, compression: str, where: str) -> None:
    if compression not in COMPRESSIONS[1:]:
        raise CorruptFileError(
            path,
            f"{where}: unsupported compression {compression!r} "
            f"(wheelcal reads {', '.join(COMPRESSIONS[1:])} and none)",
        )


def _stream_into(path: str, compression: str, data, out: bytearray, where: str):
    """Decompress into ``out``; (bytes written, whether more would have followed)."""
    try:
        if compression == "zstd":
            return _zstd_into(data, out)
        if compression == "lz4":
            return _lz4_into(data, out)
        return _bz2_into(data, out)
    except CorruptFileError:
        raise
    except Exception as exc:  # zstandard.ZstdError, lz4's RuntimeError, bz2's OSError
        raise CorruptFileError(
            path, f"{where}: {compression} data is damaged ({type(exc).__name__}: {exc})"
        ) from None


def _zstd_into(data, out: bytearray) -> tuple[int, bool]:
    import zstandard

    size = len(out)
    reader = zstandard.ZstdDecompressor().stream_reader(data, read_across_frames=True)
    view = memoryview(out)
    pos = 0
    while pos < size:
        got = reader.readinto(view[pos : pos + min(PIECE_BYTES, size - pos)])
        if got == 0:
            break
        pos += got
    return pos, pos == size and bool(reader.read(1))


def _streams_into(new_decompressor, data, out: bytearray, *, truncated: str | None):
    """Decompress concatenated streams into ``out``, never beyond one byte past its size.

    ``new_decompressor()`` makes a decompressor with ``decompress(data,
    max_length)``, ``eof``, ``unused_data`` and ``needs_input``; a stream that
    ends before its end marker raises ``OSError(truncated)`` (or stops short
    when ``truncated`` is None).  Returns the bytes written and whether there
    was more than ``out`` holds.
    """
    size = len(out)
    decompressor = new_decompressor()
    source, pos = data, 0
    while True:
        piece = decompressor.decompress(source, max_length=min(PIECE_BYTES, size - pos + 1))
        source = b""
        if pos + len(piece) > size:
            return pos, True
        out[pos : pos + len(piece)] = piece
        pos += len(piece)
        if decompressor.eof:
            rest = decompressor.unused_data
            if not rest:
                return pos, False
            decompressor, source = new_decompressor(), rest  # concatenated frames / streams
        elif not piece and decompressor.needs_input:
            if truncated is None:
                return pos, False
            raise OSError(truncated)


def _lz4_into(data, out: bytearray) -> tuple[int, bool]:
    import lz4.frame

    return _streams_into(lz4.frame.LZ4FrameDecompressor, data, out, truncated=None)


def _bz2_into(data, out: bytearray) -> tuple[int, bool]:
    import bz2

    return _streams_into(
        bz2.BZ2Decompressor,
        bytes(data),
        out,
        truncated="the bz2 stream ends before its end-of-stream marker",
    )
