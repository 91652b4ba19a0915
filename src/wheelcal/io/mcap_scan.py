"""A fast, checking walk over the records of an MCAP file (no message decoding).

MCAP (https://mcap.dev/spec) is ``<magic><Header><data section>[<summary>]
<Footer><magic>``, every record ``<opcode u8><length u64><content>``, all
integers little-endian, strings ``<u32 length><utf-8>``.  Messages sit in the
data section, loose or inside Chunk records whose content is

    message_start_time u64, message_end_time u64, uncompressed_size u64,
    uncompressed_crc u32, compression string, records_length u64, records

(``compression`` is ``""``, ``"zstd"`` or ``"lz4"`` (LZ4 frame)).  A Message
record is ``channel_id u16, sequence u32, log_time u64, publish_time u64,
data`` — 22 bytes of header, then the payload up to the record's end.

What this module does, and why it is fast:

* reads the file once, walks the top-level records, decompresses every chunk
  and **verifies every CRC the file carries** (chunk ``uncompressed_crc``, the
  DataEnd data-section CRC, the Footer summary CRC), so a damaged file is an
  error, never silently wrong numbers;
* finds the Message records inside a chunk from the MessageIndex records
  that follow it — after checking that the indexed records tile the chunk
  exactly, so the (CRC-less) index can neither hide nor invent a message —
  or, without a usable index, with a Python loop that *gallops*:
  once two consecutive messages have the same length (fixed-size messages of
  one topic, the common case), it checks all further candidate positions at
  that stride with one vectorised numpy test and accepts the longest prefix
  that matches (each accepted record proves the position of the next, so the
  prefix is exact);
* returns, per channel, the decompressed buffers with the offsets and lengths
  of that channel's message payloads, for vectorised decoders
  (:mod:`wheelcal.io.imu_cdr`, :mod:`wheelcal.io.accel_json`).

Records it does not need (indexes, statistics, attachments) are skipped by
their length, as the spec asks of readers.
"""

from __future__ import annotations

import mmap
import os
import stat
import struct
from dataclasses import dataclass, field
from enum import IntEnum
from types import MappingProxyType
from typing import Protocol

import numpy as np

from wheelcal.io.bounded_decompress import (
    MAX_BYTES,
    MAX_RATIO,
    PIECE_BYTES,
    SLACK_BYTES,
    decompress_sized,
)
from wheelcal.io.errors import CorruptFileError, NotMcapError
from wheelcal.io.file_kind import special_kind

try:  # zlib-ng's CRC-32 (SIMD: ≈ 14× zlib's here, ≈ 1.5 ms per 90 s ROS 2 recording)
    from zlib_ng.zlib_ng import crc32
except ImportError:  # pragma: no cover - a dependency; zlib computes the same CRC
    from zlib import crc32

MAGIC = b"\x89MCAP0\r\n"
MESSAGE_HEADER_BYTES = 22  # channel u16, sequence u32, log_time u64, publish_time u64
#: Between two payloads of Message records in a row: the next one's opcode, length and header.
RECORD_GAP_BYTES = 9 + MESSAGE_HEADER_BYTES
_RECORD_PREFIX = struct.Struct("<BQ")
_GALLOP_MIN = 16  # try the vectorised stride test only with this many candidates left
_GALLOP_COOLDOWN = 32  # after a failed gallop, walk at least this many records one by one


def is_mcap_file(path: str | os.PathLike) -> bool:
    """Whether *path* is one file that starts with MCAP's magic bytes."""
    try:
        with open(path, "rb") as stream:
            return stream.read(len(MAGIC)) == MAGIC
    except OSError:  # a folder (a rosbag2) or unreadable: not one MCAP file to copy
        return False


class Opcode(IntEnum):
    """MCAP record opcodes (spec, "Records")."""

    HEADER = 0x01
    FOOTER = 0x02
    SCHEMA = 0x03
    CHANNEL = 0x04
    MESSAGE = 0x05
    CHUNK = 0x06
    MESSAGE_INDEX = 0x07
    CHUNK_INDEX = 0x08
    ATTACHMENT = 0x09
    ATTACHMENT_INDEX = 0x0A
    STATISTICS = 0x0B
    METADATA = 0x0C
    METADATA_INDEX = 0x0D
    SUMMARY_OFFSET = 0x0E
    DATA_END = 0x0F


@dataclass(frozen=True)
class SchemaRecord:
    """A Schema record: how to read the messages of channels that refer to it."""

    id: int
    name: str
    encoding: str
    data: bytes = field(repr=False)


@dataclass(frozen=True)
class ChannelRecord:
    """A Channel record: topic, message encoding, schema and free-form metadata."""

    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: MappingProxyType


@dataclass(frozen=True, eq=False)
class MessageBlock:
    """Message payloads of one channel inside one buffer (a chunk or the file).

    ``payload_offsets[i]`` is where payload i starts in ``buffer`` (after the
    22-byte message header) and ``payload_lengths[i]`` its size;
    ``log_time_ns[i]`` is the record's log time.
    """

    buffer: bytes = field(repr=False)
    payload_offsets: np.ndarray
    payload_lengths: np.ndarray
    log_time_ns: np.ndarray

    @property
    def count(self) -> int:
        """Number of messages in the block."""
        return int(self.payload_offsets.size)

    def back_to_back(self) -> bool:
        """Whether the payloads are Message records in a row: only the records' heads between."""
        starts, lengths = self.payload_offsets, self.payload_lengths
        return bool(np.all(starts[1:] - (starts[:-1] + lengths[:-1]) == RECORD_GAP_BYTES))

    def span(self) -> tuple[int, int]:
        """Where the first payload starts and the last ends in ``buffer`` (a non-empty block)."""
        return int(self.payload_offsets[0]), int(
            self.payload_offsets[-1] + self.payload_lengths[-1]
        )


@dataclass(frozen=True, eq=False)
class McapScan:
    """What :func:`scan_mcap` found: schemas, channels, metadata and message blocks."""

    path: str
    profile: str
    library: str
    schemas: MappingProxyType  # id -> SchemaRecord
    channels: MappingProxyType  # id -> ChannelRecord
    metadata: tuple[tuple[str, MappingProxyType], ...]  # (name, {key: value}) in file order
    blocks: MappingProxyType  # channel id -> tuple[MessageBlock, ...]
    chunks: int
    chunks_without_crc: int
    #: channel id -> the sink that consumed its messages (see :func:`scan_mcap`).
    sinks: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))

    def message_count(self, channel_id: int) -> int:
        """Number of messages of one channel."""
        sink = self.sinks.get(channel_id)
        held = sum(block.count for block in self.blocks.get(channel_id, ()))
        return held + (sink.count if sink is not None else 0)

    def schema_of(self, channel: ChannelRecord) -> SchemaRecord | None:
        """The channel's schema (``None`` for schema id 0, "no schema")."""
        return self.schemas.get(channel.schema_id)


class _Cursor:
    """Bounds-checked reads of MCAP primitives from one record's content."""

    def __init__(self, buf: bytes, start: int, end: int, fail) -> None:
        self.buf, self.pos, self.end, self.fail = buf, start, end, fail

    def _take(self, n: int) -> int:
        if self.pos + n > self.end:
            raise self.fail("a record field runs past the end of its record")
        start = self.pos
        self.pos += n
        return start

    def u16(self) -> int:
        return int.from_bytes(self.buf[self._take(2) : self.pos], "little")

    def u32(self) -> int:
        return int.from_bytes(self.buf[self._take(4) : self.pos], "little")

    def u64(self) -> int:
        return int.from_bytes(self.buf[self._take(8) : self.pos], "little")

    def raw(self, n: int) -> bytes:
        return bytes(self.buf[self._take(n) : self.pos])

    def view(self, n: int) -> memoryview:
        """``n`` bytes without a copy (chunk records can be megabytes)."""
        return memoryview(self.buf)[self._take(n) : self.pos]

    def string(self) -> str:
        raw = self.raw(self.u32())
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError:
            raise self.fail("a string field is not valid UTF-8") from None

    def string_map(self) -> dict[str, str]:
        size = self.u32()
        stop = self.pos + size
        if stop > self.end:
            raise self.fail("a key-value map runs past the end of its record")
        out = {}
        while self.pos < stop:
            key = self.string()
            out[key] = self.string()
        return out


def _gather_u64(arr: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Little-endian u64 values starting at each of ``positions`` in a uint8 array."""
    return _gather_le(arr, positions, "<u8")


def _gather_le(arr: np.ndarray, positions: np.ndarray, dtype: str) -> np.ndarray:
    """Values of ``dtype`` starting at each of ``positions`` in a uint8 array (a copy).

    Fixed-size messages sit at one stride (the common case): then one strided
    view, copied, instead of a gather through an (N, itemsize) index.
    """
    size = np.dtype(dtype).itemsize
    if positions.size > 1 and positions[0] >= 0 and positions[-1] + size <= arr.size:
        step = int(positions[1] - positions[0])
        if step > 0 and np.all(np.diff(positions) == step):
            view = np.ndarray(
                (positions.size,), dtype, buffer=arr, offset=int(positions[0]), strides=(step,)
            )
            return view.copy()
    raw = arr[positions[:, None] + np.arange(size)]
    return raw.view(dtype).reshape(-1)


def _walk_records(buf: bytes, start: int, end: int, fail) -> tuple[np.ndarray, ...]:
    """Opcodes, record starts and content lengths of the records in ``buf[start:end]``.

    Raises the error made by ``fail(text)`` if a record runs past ``end``.
    """
    arr = np.frombuffer(buf, dtype=np.uint8)
    unpack = _RECORD_PREFIX.unpack_from
    ops: list[int] = []
    starts: list[int] = []
    lengths: list[int] = []
    bulk: list[tuple[int, np.ndarray, int]] = []  # (index in lists, starts, length)
    pos = start
    previous_message_length = -1
    cooldown = 0
    backoff = _GALLOP_COOLDOWN
    while pos < end:
        if pos + 9 > end:
            raise fail(f"record header at byte {pos} is cut off")
        op, length = unpack(buf, pos)
        nxt = pos + 9 + length
        if nxt > end:
            raise fail(
                f"record at byte {pos} (opcode 0x{op:02x}) needs {length} bytes "
                f"but only {end - pos - 9} remain"
            )
        ops.append(op)
        starts.append(pos)
        lengths.append(length)
        pos = nxt
        if op != Opcode.MESSAGE:
            previous_message_length = -1
            continue
        if cooldown:
            cooldown -= 1
        elif length == previous_message_length:
            stride = length + 9
            candidates = (end - pos) // stride
            if candidates >= _GALLOP_MIN:
                at = pos + stride * np.arange(candidates, dtype=np.int64)
                ok = (arr[at] == Opcode.MESSAGE) & (_gather_u64(arr, at + 1) == length)
                bad = np.flatnonzero(~ok)
                accepted = int(bad[0]) if bad.size else candidates
                if accepted:
                    bulk.append((len(ops), at[:accepted], length))
                    pos += accepted * stride
                # Variable-length messages (e.g. JSON) rarely gallop: back off exponentially.
                if accepted < _GALLOP_MIN:
                    cooldown = backoff
                    backoff = min(2 * backoff, 1 << 16)
                else:
                    backoff = _GALLOP_COOLDOWN
        previous_message_length = length
    if not bulk:
        return (
            np.array(ops, dtype=np.uint8),
            np.array(starts, dtype=np.int64),
            np.array(lengths, dtype=np.int64),
        )
    # Splice the galloped runs back in at the places they were found.
    op_parts, start_parts, length_parts = [], [], []
    cut = 0
    for index, run_starts, length in bulk:
        op_parts += [np.array(ops[cut:index], np.uint8), np.full(run_starts.size, 5, np.uint8)]
        start_parts += [np.array(starts[cut:index], np.int64), run_starts]
        length_parts += [
            np.array(lengths[cut:index], np.int64),
            np.full(run_starts.size, length, np.int64),
        ]
        cut = index
    op_parts.append(np.array(ops[cut:], np.uint8))
    start_parts.append(np.array(starts[cut:], np.int64))
    length_parts.append(np.array(lengths[cut:], np.int64))
    return np.concatenate(op_parts), np.concatenate(start_parts), np.concatenate(length_parts)


def _records_from_index(
    buf: bytes, index_offsets: np.ndarray, fail
) -> tuple[np.ndarray, ...] | None:
    """Record table of a chunk from its MessageIndex offsets, or None if they do not fit.

    The index is not trusted: every indexed position must hold a Message
    record, and the records must tile the chunk exactly, the stretches
    between them holding only non-message records (walked one by one, e.g.
    the Schema and Channel records at a chunk's start).  So no message can be
    missed or invented.
    """
    size = len(buf)
    at = index_offsets.astype(np.int64)
    if at.size > 1 and not np.all(at[1:] > at[:-1]):
        at = np.unique(at)
    if at.size == 0 or at[0] < 0 or at[-1] + 9 > size:
        return None
    arr = np.frombuffer(buf, dtype=np.uint8)
    if np.any(arr[at] != Opcode.MESSAGE):
        return None
    lengths = _gather_u64(arr, at + 1).astype(np.int64)
    ends = at + 9 + lengths
    if np.any(lengths < 0) or ends[-1] > size or np.any(ends[:-1] > at[1:]):
        return None
    gap_from = np.concatenate([[0], ends])
    gap_to = np.concatenate([at, [size]])
    parts = [(at, lengths)]
    for lo, hi in zip(
        gap_from[gap_from < gap_to].tolist(), gap_to[gap_from < gap_to].tolist(), strict=True
    ):
        g_ops, g_starts, g_lengths = _walk_records(buf, lo, hi, fail)
        if np.any(g_ops == Opcode.MESSAGE):
            return None  # the index misses a message: walk the whole chunk instead
        parts.append((g_starts, g_lengths, g_ops))
    starts = np.concatenate([p[0] for p in parts])
    lens = np.concatenate([p[1] for p in parts])
    ops = np.concatenate([np.full(at.size, Opcode.MESSAGE, np.uint8)] + [p[2] for p in parts[1:]])
    order = np.argsort(starts, kind="stable")
    return ops[order], starts[order], lens[order]


def _message_index_offsets(buf: bytes, starts, lengths) -> np.ndarray:
    """All (channel-independent) record offsets listed by MessageIndex records."""
    out = []
    for start, length in zip(starts.tolist(), lengths.tolist(), strict=True):
        content = start + 9
        size = int.from_bytes(buf[content + 2 : content + 6], "little")
        if size % 16 or 6 + size > length:
            return np.empty(0, np.int64)
        pairs = np.frombuffer(buf, dtype="<u8", count=size // 8, offset=content + 6)
        out.append(pairs[1::2])
    return np.concatenate(out) if out else np.empty(0, np.int64)


#: The caps of :mod:`wheelcal.io.bounded_decompress` (the same for every reader).
MAX_CHUNK_RATIO = MAX_RATIO
MAX_CHUNK_SLACK_BYTES = SLACK_BYTES
MAX_CHUNK_BYTES = MAX_BYTES
_PIECE_BYTES = PIECE_BYTES  # CRCs are computed in pieces of this size


def _decompress(path: str, compression: str, data, size: int, where: str):
    """The chunk's records, decompressed into one buffer of the claimed ``size``.

    MCAP chunks are stored as is, or compressed with zstd or lz4 (spec); the
    claim is judged before anything is allocated and the data decompressed in
    bounded pieces (:func:`~wheelcal.io.bounded_decompress.decompress_sized`).
    """
    if compression not in ("", "zstd", "lz4"):
        raise CorruptFileError(
            path, f"{where}: unsupported chunk compression {compression!r} (need zstd, lz4, none)"
        )
    return decompress_sized(path, compression, data, size, where)


class MessageSink(Protocol):
    """Consumes one channel's message blocks as the scan finds them (so chunks can go)."""

    count: int  # messages consumed

    def add(self, block: MessageBlock) -> None:
        """Take the messages of one block (the block's buffer is not kept)."""


class _Collector:
    """Accumulates schemas, channels, metadata and message blocks during a scan."""

    def __init__(self, path: str, sink_for=None) -> None:
        self.path = path
        self.schemas: dict[int, SchemaRecord] = {}
        self.channels: dict[int, ChannelRecord] = {}
        self.metadata: list[tuple[str, MappingProxyType]] = []
        self.blocks: dict[int, list[MessageBlock]] = {}
        self.sink_for = sink_for
        self.sinks: dict[int, MessageSink] = {}
        self.chunks = 0
        self.chunks_without_crc = 0

    def fail(self, where: str):
        return lambda text: CorruptFileError(self.path, f"{where}: {text}")

    def definitions(self, buf: bytes, ops, starts, lengths, where: str) -> None:
        """Schema, Channel and (outside chunks) Metadata records."""
        wanted = (ops == Opcode.SCHEMA) | (ops == Opcode.CHANNEL) | (ops == Opcode.METADATA)
        for op, start, length in zip(
            ops[wanted].tolist(), starts[wanted].tolist(), lengths[wanted].tolist(), strict=True
        ):
            cur = _Cursor(buf, start + 9, start + 9 + length, self.fail(f"{where}, byte {start}"))
            if op == Opcode.SCHEMA:
                sid, name, enc = cur.u16(), cur.string(), cur.string()
                schema = SchemaRecord(sid, name, enc, cur.raw(cur.u32()))
                self._define(self.schemas, schema, f"{where}, byte {start}", "schema")
            elif op == Opcode.CHANNEL:
                cid, sid, topic, enc = cur.u16(), cur.u16(), cur.string(), cur.string()
                meta = MappingProxyType(cur.string_map())
                channel = ChannelRecord(cid, sid, topic, enc, meta)
                self._define(self.channels, channel, f"{where}, byte {start}", "channel")
            else:
                name = cur.string()
                self.metadata.append((name, MappingProxyType(cur.string_map())))

    def _define(self, table: dict, record, where: str, kind: str) -> None:
        """Add a Schema or Channel record; the same id defined otherwise is refused.

        The spec lets a writer repeat a record (in chunks, in the summary) but
        never give one id two meanings: the messages of the two could not be
        told apart (they would pass for one stream, with repeated stamps).
        """
        known = table.get(record.id)
        if known is not None and _differs(known, record):
            what = (
                f"topic {known.topic!r} and topic {record.topic!r}"
                if kind == "channel"
                else f"{known.name!r} and {record.name!r}"
            )
            if kind == "channel" and known.topic == record.topic:
                what = f"topic {known.topic!r} twice with different encodings, schemas or metadata"
            raise CorruptFileError(
                self.path,
                f"{where}: {kind} id {record.id} is defined twice, as {what}: their messages "
                "cannot be told apart (a file merged from two recordings without renumbering?)",
            )
        table[record.id] = record

    def chunk(self, buf, i: int, stop: int, table: tuple[np.ndarray, ...]) -> None:
        """Record ``i`` of the data section's ``table``, a Chunk: decompressed, checked, read.

        The records after it up to ``stop`` (the next chunk) hold its
        MessageIndex records, which list its messages (spec) and spare a walk
        through the decompressed records.  The chunk's pages of the mapped file
        are released when it is done.
        """
        ops, starts, lengths = table
        chunk_start, chunk_length = int(starts[i]), int(lengths[i])
        follow = slice(i + 1, stop)
        is_index = ops[follow] == Opcode.MESSAGE_INDEX
        index_offsets = _message_index_offsets(
            buf, starts[follow][is_index], lengths[follow][is_index]
        )
        where = f"chunk at byte {chunk_start}"
        cur = _Cursor(buf, chunk_start + 9, chunk_start + 9 + chunk_length, self.fail(where))
        cur.u64()  # message_start_time
        cur.u64()  # message_end_time
        size, crc = cur.u64(), cur.u32()
        compression = cur.string()
        records = cur.view(cur.u64())
        data = _decompress(self.path, compression, records, size, where)
        if crc == 0:
            self.chunks_without_crc += 1  # the writer chose not to compute it (spec: 0 = absent)
        elif (computed := crc32(data)) != crc:
            raise CorruptFileError(
                self.path,
                f"{where}: CRC mismatch, the chunk's data is damaged (stored {crc:#010x}, "
                f"computed {computed:#010x})",
            )
        inner = None
        if index_offsets.size:
            inner = _records_from_index(data, index_offsets, self.fail(where))
        if inner is None:
            inner = _walk_records(data, 0, len(data), self.fail(where))
        c_ops, c_starts, c_lengths = inner
        self.definitions(data, c_ops, c_starts, c_lengths, where)
        self.messages(data, c_ops, c_starts, c_lengths, where)
        self.chunks += 1
        del data, inner, c_ops, c_starts, c_lengths, records
        _release(buf, chunk_start, chunk_start + 9 + chunk_length)

    def scan(self, profile: str, library: str) -> McapScan:
        """What was found, once every record was read; refuses messages of undefined channels."""
        for cid in list(self.blocks) + list(self.sinks):
            if cid not in self.channels:
                raise CorruptFileError(
                    self.path, f"messages refer to channel {cid}, which is never defined"
                )
        return McapScan(
            path=self.path,
            profile=profile,
            library=library,
            schemas=MappingProxyType(self.schemas),
            channels=MappingProxyType(self.channels),
            metadata=tuple(self.metadata),
            blocks=MappingProxyType({k: tuple(v) for k, v in self.blocks.items()}),
            chunks=self.chunks,
            chunks_without_crc=self.chunks_without_crc,
            sinks=MappingProxyType(self.sinks),
        )

    def messages(self, buf: bytes, ops, starts, lengths, where: str) -> None:
        """Group the Message records of ``buf`` by channel."""
        is_msg = ops == Opcode.MESSAGE
        if not np.any(is_msg):
            return
        m_starts, m_lengths = starts[is_msg], lengths[is_msg]
        if np.any(m_lengths < MESSAGE_HEADER_BYTES):
            raise CorruptFileError(self.path, f"{where}: a message record is too short")
        arr = np.frombuffer(buf, dtype=np.uint8)
        content = m_starts + 9
        channel = _gather_le(arr, content, "<u2")
        log_time = _gather_u64(arr, content + 6).astype(np.int64)
        payload_offsets = content + MESSAGE_HEADER_BYTES
        payload_lengths = m_lengths - MESSAGE_HEADER_BYTES
        for cid in np.unique(channel).tolist():
            sel = channel == cid
            block = MessageBlock(buf, payload_offsets[sel], payload_lengths[sel], log_time[sel])
            sink = self.sinks.get(cid)
            if sink is None and cid not in self.blocks and self.sink_for is not None:
                known = self.channels.get(cid)  # a channel defined after its messages: keep
                if known is not None:
                    sink = self.sink_for(known, self.schemas.get(known.schema_id))
                    if sink is not None:
                        self.sinks[cid] = sink
            if sink is not None:
                sink.add(block)
            else:
                self.blocks.setdefault(cid, []).append(block)


def scan_mcap(path: str | os.PathLike, sink_for=None) -> McapScan:
    """Walk an MCAP file, verify its CRCs, and index its messages by channel.

    Parameters
    ----------
    path:
        The file.
    sink_for:
        Optional ``(ChannelRecord, SchemaRecord | None) -> MessageSink | None``,
        asked once per channel at its first messages: a sink consumes that
        channel's blocks as they are found (decoding them), so no chunk is kept
        after it was walked; ``None`` keeps the channel's blocks in ``blocks``.

    Returns
    -------
    McapScan
        Schemas, channels, ``Metadata`` records and per-channel message blocks.

    Raises
    ------
    NotMcapError
        Empty file, or not an MCAP file (wrong magic bytes).
    CorruptFileError
        Truncated file, a record that runs past its container, damaged
        compressed data, or any CRC mismatch.
    """
    name = str(path)
    buf = _map_file(name)
    ops, starts, lengths = _records(name, buf)
    footer = ops.size - 1
    col = _Collector(name, sink_for)
    header = _Cursor(
        buf, int(starts[0]) + 9, int(starts[0]) + 9 + int(lengths[0]), col.fail("header")
    )
    profile, library = header.string(), header.string()

    data_end_at = np.flatnonzero(ops == Opcode.DATA_END)
    data_stop = int(data_end_at[0]) if data_end_at.size else footer

    # Data section: loose definitions and messages, metadata, and chunks.
    d_ops, d_starts, d_lengths = ops[:data_stop], starts[:data_stop], lengths[:data_stop]
    col.definitions(buf, d_ops, d_starts, d_lengths, "data section")
    col.messages(buf, d_ops, d_starts, d_lengths, "data section")
    chunk_at = np.flatnonzero(d_ops == Opcode.CHUNK)
    for k, i in enumerate(chunk_at.tolist()):
        # The MessageIndex records that follow a chunk (spec) list its messages.
        stop = int(chunk_at[k + 1]) if k + 1 < chunk_at.size else d_ops.size
        col.chunk(buf, i, stop, (d_ops, d_starts, d_lengths))
    # After the chunks, so a damaged chunk is reported as precisely as possible.
    _check_section_crcs(name, buf, starts, data_end_at, footer)
    # Summary section: repeated schemas and channels (harmless duplicates by id).
    s_ops, s_starts, s_lengths = (
        ops[data_stop:footer],
        starts[data_stop:footer],
        lengths[data_stop:footer],
    )
    keep = (s_ops == Opcode.SCHEMA) | (s_ops == Opcode.CHANNEL)
    col.definitions(buf, s_ops[keep], s_starts[keep], s_lengths[keep], "summary section")
    return col.scan(profile, library)


def _records(name: str, buf) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Opcodes, starts and lengths of the file's top-level records, from Header to Footer.

    Refuses what is no MCAP file (magic), and a file that is truncated or whose
    records do not run from a Header to a Footer and the end magic.
    """
    if buf[: len(MAGIC)] != MAGIC:
        hint = " (it looks like text, e.g. a CSV: see `wheelcal convert`)" if _is_text(buf) else ""
        raise NotMcapError(name, f"not an MCAP file: it does not start with the MCAP magic{hint}")
    size = len(buf)
    complete = size >= 2 * len(MAGIC) and buf[size - len(MAGIC) :] == MAGIC
    end = size - len(MAGIC) if complete else size
    ops, starts, lengths = _walk_records(
        buf,
        len(MAGIC),
        end,
        lambda text: CorruptFileError(
            name, f"the file is truncated or damaged: {text} (file size {size} bytes)"
        ),
    )
    if not complete or ops.size == 0 or ops[-1] != Opcode.FOOTER:
        raise CorruptFileError(
            name,
            "the file is truncated: it has no footer and end magic (the recording was cut "
            "off; `mcap recover` can salvage the complete chunks)",
        )
    if ops[0] != Opcode.HEADER:
        raise CorruptFileError(name, "the first record is not an MCAP Header")
    return ops, starts, lengths


def _check_section_crcs(name, buf, starts, data_end_at, footer) -> None:
    """The DataEnd data-section CRC and the Footer summary CRC, where present (non-zero)."""
    if data_end_at.size:
        at = int(starts[data_end_at[0]])
        stored = int.from_bytes(buf[at + 9 : at + 13], "little")
        if stored and _crc32(buf, 0, at) != stored:
            raise CorruptFileError(
                name, "data-section CRC mismatch: the file's data section is damaged"
            )
    f_at = int(starts[footer])
    summary_start = int.from_bytes(buf[f_at + 9 : f_at + 17], "little")
    summary_crc = int.from_bytes(buf[f_at + 25 : f_at + 29], "little")
    if summary_crc and summary_start:
        # Spec: CRC of the summary section through the footer's summary_offset_start field.
        if _crc32(buf, summary_start, f_at + 25) != summary_crc:
            raise CorruptFileError(name, "summary CRC mismatch: the file's summary is damaged")


def _map_file(name: str):
    """The file's bytes, memory-mapped (read-only); errors for what is no readable file.

    Mapped, not read: the scan walks the file once and hands each chunk's pages
    back to the kernel (:func:`_release`), so a long recording does not sit in
    memory twice (compressed and decoded).  A FIFO, device or directory is
    refused before it is opened (reading a FIFO would wait for a writer).
    """
    try:
        info = os.stat(name)
    except FileNotFoundError:
        raise NotMcapError(name, "no such file") from None
    except OSError as exc:
        raise NotMcapError(name, f"cannot be read ({exc.strerror})") from None
    if stat.S_ISDIR(info.st_mode):
        raise NotMcapError(name, "is a directory, not an MCAP recording")
    kind = special_kind(info.st_mode)
    if kind is not None:
        raise NotMcapError(
            name, f"is {kind}: wheelcal reads recordings from regular files (save it first)"
        )
    if info.st_size == 0:
        raise NotMcapError(name, "the file is empty (0 bytes), not an MCAP recording")
    try:
        with open(name, "rb") as stream:
            return mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ)
    except (OSError, ValueError) as exc:
        raise NotMcapError(
            name, f"cannot be read ({getattr(exc, 'strerror', None) or exc})"
        ) from None


def _release(buf, start: int, stop: int) -> None:
    """Give the pages of ``buf[start:stop]`` back to the kernel (a mapped file re-reads them)."""
    if isinstance(buf, mmap.mmap) and hasattr(mmap, "MADV_DONTNEED"):
        aligned = start - start % mmap.PAGESIZE
        if stop > aligned:
            buf.madvise(mmap.MADV_DONTNEED, aligned, stop - aligned)


def _crc32(buf, start: int, stop: int) -> int:
    """CRC-32 of ``buf[start:stop]``, in pieces whose pages are released after use."""
    crc = 0
    view = memoryview(buf)
    for at in range(start, stop, _PIECE_BYTES):
        end = min(at + _PIECE_BYTES, stop)
        crc = crc32(view[at:end], crc)
        _release(buf, at, end)
    view.release()
    return crc


def _is_text(buf: bytes) -> bool:
    head = buf[:512]
    try:
        head.decode("utf-8")
    except UnicodeDecodeError:
        return False
    return b"\x00" not in head


def _differs(known, record) -> bool:
    """Whether two Schema or Channel records with one id say different things."""
    if isinstance(known, ChannelRecord):
        return (known.schema_id, known.topic, known.message_encoding, dict(known.metadata)) != (
            record.schema_id,
            record.topic,
            record.message_encoding,
            dict(record.metadata),
        )
    return (known.name, known.encoding, known.data) != (record.name, record.encoding, record.data)
