r"""ROS 1 bags (``.bag``, format 2.0) as an MCAP-like scan, vectorised over the bag's index.

The format (ROS wiki, "Bags/Format/2.0"): after ``#ROSBAG V2.0\n`` come
records, each ``uint32 header_len``, header fields (``uint32 len`` +
``name=value``), ``uint32 data_len``, data.  The *bag header* gives
``index_pos``, where the *connection* records (topic, type, message
definition) and the *chunk info* records are.  Messages live in *chunks*
(``compression`` none, bz2 or lz4), and each chunk is followed by *index data*
records: per connection, an array of (``time``, ``offset``) of its messages
in the uncompressed chunk.

The scan reads that structure record by record (a few per chunk), and the
messages themselves with numpy: the index gives every message record's
offset, so its data's position and length are two vectorised gathers — no
per-message Python.  Each chunk's messages of a wanted connection go to the
same sinks as an MCAP scan's (the ROS 1 Imu decoder,
:mod:`wheelcal.io.imu_ros1`).  A bag that was never indexed (a recording cut
off) is refused with the fix (``rosbag reindex``); bags carry no checksums.
"""

from __future__ import annotations

import os
import re
import struct
from types import MappingProxyType

import numpy as np

from wheelcal.io.bounded_decompress import decompress_sized
from wheelcal.io.errors import CorruptFileError, NotMcapError
from wheelcal.io.mcap_scan import (
    ChannelRecord,
    McapScan,
    MessageBlock,
    SchemaRecord,
    _map_file,
)

MAGIC = b"#ROSBAG V2.0\n"
#: ``#ROSBAG V<major>.<minor>`` — the line every bag version starts with.
_VERSION_LINE = re.compile(rb"#ROSBAG V(\d+)\.(\d+)\n")
_OP_MSG_DATA, _OP_BAG_HEADER, _OP_INDEX_DATA = 0x02, 0x03, 0x04
_OP_CHUNK, _OP_CHUNK_INFO, _OP_CONNECTION = 0x05, 0x06, 0x07
_RECORD_NAMES = {
    _OP_MSG_DATA: "message data",
    _OP_BAG_HEADER: "bag header",
    _OP_INDEX_DATA: "index data",
    _OP_CHUNK: "chunk",
    _OP_CHUNK_INFO: "chunk info",
    _OP_CONNECTION: "connection",
}
_U32 = struct.Struct("<I")
_INDEX_ENTRY = np.dtype([("sec", "<u4"), ("nsec", "<u4"), ("offset", "<u4")])


class _Reader:
    """Bounds-checked records of one bag (header fields as a dict of raw bytes)."""

    def __init__(self, name: str, buf) -> None:
        self.name, self.buf, self.size = name, buf, len(buf)

    def fail(self, where: int, text: str) -> CorruptFileError:
        return CorruptFileError(self.name, f"byte {where}: {text} (a truncated or damaged bag?)")

    def u32(self, at: int) -> int:
        if at + 4 > self.size:
            raise self.fail(at, "a record runs past the end of the file")
        return _U32.unpack_from(self.buf, at)[0]

    def record(self, at: int) -> tuple[dict[str, bytes], int, int, int]:
        """(header fields, data start, data length, next record) of the record at ``at``."""
        header_len = self.u32(at)
        fields = self.fields(at + 4, header_len)
        data_len = self.u32(at + 4 + header_len)
        data_at = at + 8 + header_len
        if data_at + data_len > self.size:
            raise self.fail(at, "a record runs past the end of the file")
        return fields, data_at, data_len, data_at + data_len

    def integer(self, fields: dict[str, bytes], name: str, at: int, width: int = 4) -> int:
        """The little-endian ``width``-byte field ``name`` of the record at ``at``, checked."""
        what = _RECORD_NAMES.get(_op(fields), "a")
        if name not in fields:
            raise self.fail(at, f"the {what} record's header has no {name!r} field")
        raw = fields[name]
        if len(raw) != width:
            raise self.fail(
                at,
                f"the {what} record's {name!r} field holds {len(raw)} bytes, not {width} "
                f"(a {8 * width}-bit integer)",
            )
        return int.from_bytes(raw, "little")

    def fields(self, at: int, length: int) -> dict[str, bytes]:
        fields, end = {}, at + length
        if end > self.size:
            raise self.fail(at, "a record header runs past the end of the file")
        while at < end:
            size = self.u32(at)
            raw = bytes(self.buf[at + 4 : at + 4 + size])
            if at + 4 + size > end or b"=" not in raw:
                raise self.fail(at, "a record header field is malformed")
            key, _, value = raw.partition(b"=")
            fields[key.decode("ascii", "replace")] = value
            at += 4 + size
        return fields


def _op(fields: dict[str, bytes]) -> int:
    """The record's op code (0xff, no known record, when the field is missing or empty)."""
    op = fields.get("op", b"")
    return op[0] if len(op) == 1 else 0xFF


def _refuse_other_version(name: str, head: bytes) -> None:
    """A bag of another format version is named as such (not "not an MCAP file")."""
    version = _VERSION_LINE.match(head)
    if version is None:
        raise NotMcapError(name, "not a ROS 1 bag of format 2.0")
    major, minor = (int(v) for v in version.groups())
    raise NotMcapError(
        name,
        f"a ROS bag of format {major}.{minor}; wheelcal reads format 2.0 (ROS 1 since "
        "C Turtle, 2010): rewrite it with ROS 1's rosbag, which writes 2.0 "
        "(`rosbag fix old.bag new.bag`)",
    )


def scan_rosbag1(path: str | os.PathLike, sink_for=None) -> McapScan:
    """Scan a ROS 1 bag into the MCAP scan's form (see the module docstring).

    Raises
    ------
    NotMcapError
        Not a version 2.0 bag.
    CorruptFileError
        Truncated or damaged records, an unindexed bag, damaged compressed chunks.
    """
    name = str(path)
    buf = _map_file(name)
    if bytes(buf[: len(MAGIC)]) != MAGIC:
        _refuse_other_version(name, bytes(buf[:32]))
    reader = _Reader(name, buf)
    fields, _, _, _ = reader.record(len(MAGIC))
    if _op(fields) != _OP_BAG_HEADER:
        raise reader.fail(len(MAGIC), "the bag header record is missing")
    index_pos = reader.integer(fields, "index_pos", len(MAGIC), width=8)
    if index_pos == 0 or index_pos >= reader.size:
        raise CorruptFileError(
            name,
            "the bag has no index (its recording was cut off before rosbag closed it); "
            "run `rosbag reindex` on it first",
        )
    schemas: dict[int, SchemaRecord] = {}
    channels: dict[int, ChannelRecord] = {}
    chunk_positions = []
    at = index_pos
    while at < reader.size:
        record_at = at
        fields, data_at, data_len, at = reader.record(at)
        op = _op(fields)
        if op == _OP_CONNECTION:
            conn = reader.integer(fields, "conn", record_at)
            info = reader.fields(data_at, data_len)
            type_name = info.get("type", b"").decode("utf-8", "replace")
            schemas[conn] = SchemaRecord(
                conn, type_name, "ros1msg", info.get("message_definition", b"")
            )
            meta = {k: v.decode("utf-8", "replace") for k, v in info.items() if k != "type"}
            meta.pop("message_definition", None)
            topic = fields.get("topic", info.get("topic", b"")).decode("utf-8", "replace")
            channels[conn] = ChannelRecord(conn, conn, topic, "ros1", MappingProxyType(meta))
        elif op == _OP_CHUNK_INFO:
            chunk_positions.append(reader.integer(fields, "chunk_pos", record_at, width=8))
    sinks = {}
    for conn, channel in channels.items():
        sink = sink_for(channel, schemas[conn]) if sink_for is not None else None
        if sink is not None:
            sinks[conn] = sink
    for chunk_at in sorted(chunk_positions):
        _read_chunk(reader, chunk_at, sinks)
    return McapScan(
        path=name,
        profile="ros1",
        library="rosbag 2.0",
        schemas=MappingProxyType(schemas),
        channels=MappingProxyType(channels),
        metadata=(),
        blocks=MappingProxyType({}),
        chunks=len(chunk_positions),
        chunks_without_crc=0,
        sinks=MappingProxyType(sinks),
    )


def _read_chunk(reader: _Reader, at: int, sinks: dict) -> None:
    """One chunk's messages, through its index data records, into the sinks."""
    fields, data_at, data_len, after = reader.record(at)
    if _op(fields) != _OP_CHUNK:
        raise reader.fail(at, "a chunk info points to no chunk")
    size = reader.integer(fields, "size", at)
    indexes = []
    while after < reader.size:  # the chunk's index data records follow it
        index, index_at, index_len, next_at = reader.record(after)
        if _op(index) != _OP_INDEX_DATA:
            break
        conn, count = reader.integer(index, "conn", after), reader.integer(index, "count", after)
        indexes.append((conn, count, index_at))
        after = next_at
        if index_len != 12 * indexes[-1][1]:
            raise reader.fail(index_at, "an index data record has the wrong length")
    wanted = [(conn, count, where) for conn, count, where in indexes if conn in sinks]
    if not wanted:
        return
    chunk = _decompress(reader, fields, data_at, data_len, size, at)
    arr = np.frombuffer(chunk, dtype=np.uint8)
    for conn, count, where in wanted:
        entries = np.frombuffer(reader.buf, dtype=_INDEX_ENTRY, count=count, offset=where)
        sinks[conn].add(_messages(reader, arr, entries, at))


def _messages(reader: _Reader, arr: np.ndarray, entries: np.ndarray, chunk_at: int) -> MessageBlock:
    """The message data records at the index's offsets, as a block (positions by gathers)."""
    record = entries["offset"].astype(np.int64)
    if record.size and int(record.max()) + 8 > arr.size:
        raise reader.fail(chunk_at, "an index entry points past the end of its chunk")
    header_len = _gather_u32(arr, record)
    length_at = record + 4 + header_len
    if length_at.size and int(length_at.max()) + 4 > arr.size:
        raise reader.fail(chunk_at, "a message record runs past the end of its chunk")
    data_len = _gather_u32(arr, length_at)
    data_at = length_at + 4
    if data_at.size and int((data_at + data_len).max()) > arr.size:
        raise reader.fail(chunk_at, "a message runs past the end of its chunk")
    log_time = entries["sec"].astype(np.int64) * 1_000_000_000 + entries["nsec"]
    return MessageBlock(arr, data_at, data_len, log_time)


def _gather_u32(arr: np.ndarray, at: np.ndarray) -> np.ndarray:
    raw = arr[at[:, None] + np.arange(4)]
    return raw.view("<u4").reshape(-1).astype(np.int64)


def _decompress(reader: _Reader, fields, data_at: int, data_len: int, size: int, at: int):
    """The chunk's records, uncompressed (none, bz2 or lz4 — roslz4 is the LZ4 frame format).

    Bounded as every reader's (:mod:`wheelcal.io.bounded_decompress`): the
    chunk's ``size`` is judged before anything is allocated.
    """
    compression = fields.get("compression", b"none").decode("ascii", "replace")
    raw = reader.buf[data_at : data_at + data_len]
    if compression not in ("none", "bz2", "lz4"):
        raise reader.fail(at, f"unknown chunk compression {compression!r} (need none, bz2, lz4)")
    where = f"chunk at byte {at}"
    return decompress_sized(
        reader.name, "" if compression == "none" else compression, raw, size, where
    )
