"""rosbag2 in SQLite (``.db3``, the default storage up to ROS 2 Humble) as an MCAP-like scan.

A rosbag2 ``.db3`` is an SQLite database: ``topics(id, name, type,
serialization_format, …)`` and ``messages(id, topic_id, timestamp, data)``,
``data`` being the CDR message exactly as in an MCAP file (and, from Iron on,
``message_definitions`` with the ``.msg`` text).  The scan reads each wanted
topic's rows in one query, joins their blobs into one buffer and hands it to
the same sinks as the MCAP scan (:func:`~wheelcal.io.mcap_scan.scan_mcap`), so
the CDR Imu decoder, the checks and the repairs are the MCAP path's — only the
container differs.  Reading is in batches of :data:`BATCH_ROWS` messages, so
memory stays bounded for any length.

A rosbag2 *folder* (``metadata.yaml`` beside the storage files) is read too:
its SQLite files in order (their topics merged by name), or its one MCAP file.
Messages compressed one by one (``compression_mode: message``, zstd) are
decompressed as they are read; a folder compressed file by file
(``compression_mode: file``: ``bag_0.db3.zstd``) is decompressed into a
temporary folder, read, and the copy removed (no ROS install needed; the same
as ``zstd -d`` by hand).  SQLite stores no checksums: unlike MCAP's CRCs,
damage inside a blob is found only by the decoder's layout checks.

The database is opened read-only and immutable with ``apsw`` (the SQLite
binding ``rosbags`` uses; ≈ 1.4× faster here than the standard library's
``sqlite3``, which is the fallback).
"""

from __future__ import annotations

import dataclasses
import itertools
import os
import tempfile
from pathlib import Path
from types import MappingProxyType

import numpy as np

from wheelcal.io.bounded_decompress import decompress_unsized, limit_bytes
from wheelcal.io.errors import CorruptFileError, NotMcapError
from wheelcal.io.input_file import read_bounded
from wheelcal.io.mcap_scan import ChannelRecord, McapScan, MessageBlock, SchemaRecord, scan_mcap

#: Messages per block handed to a sink (bounded memory for long bags).
BATCH_ROWS = 65_536
_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"


def _connect(path: Path):
    """A read-only, immutable connection (apsw if installed, else sqlite3)."""
    uri = f"file:{path.resolve().as_posix()}?immutable=1&mode=ro"
    try:
        import apsw
    except ImportError:
        import sqlite3

        return sqlite3.connect(uri, uri=True), (sqlite3.Error,)
    flags = apsw.SQLITE_OPEN_READONLY | apsw.SQLITE_OPEN_URI
    return apsw.Connection(uri, flags=flags), (apsw.Error,)


def _bag_files(path: Path) -> tuple[list[Path], dict]:
    """The storage files of a rosbag2 folder (from metadata.yaml) and its bag information."""
    import yaml

    where = path / "metadata.yaml"
    try:
        text = read_bounded(where, "rosbag2 metadata").decode("utf-8")
    except UnicodeDecodeError as exc:
        raise CorruptFileError(
            where, f"is not UTF-8 text (byte {exc.start}: {exc.reason}), so not rosbag2 metadata"
        ) from None
    except OSError as exc:
        raise CorruptFileError(where, f"cannot be read ({exc.strerror or exc})") from None
    try:
        meta = yaml.safe_load(text)
        info = meta["rosbag2_bagfile_information"]
        files = [path / Path(name).name for name in info["relative_file_paths"]]
        info.get("compression_mode")
    except RecursionError:
        raise CorruptFileError(where, "is not rosbag2 metadata (nested too deeply)") from None
    except (yaml.YAMLError, KeyError, TypeError, AttributeError) as exc:
        raise CorruptFileError(where, f"is not rosbag2 metadata ({exc})") from None
    missing = [f.name for f in files if not f.is_file()]
    if missing:
        raise CorruptFileError(path, f"storage files named in metadata.yaml are missing: {missing}")
    return files, info


def scan_rosbag2(path: str | os.PathLike, sink_for=None) -> McapScan:
    """Scan a rosbag2 ``.db3`` file or folder into the MCAP scan's form.

    Raises
    ------
    NotMcapError
        Not a rosbag2 database (no ``topics``/``messages`` tables).
    CorruptFileError
        A database that cannot be read, or a folder whose metadata or files
        do not check out.
    """
    name = str(path)
    bag = Path(path)
    if not bag.is_dir():
        return _scan_storage(name, [bag], {}, sink_for)
    files, info = _bag_files(bag)
    mode = str(info.get("compression_mode") or "").lower()
    if mode != "file":
        return _scan_storage(name, files, info, sink_for, zstd_messages=mode == "message")
    with tempfile.TemporaryDirectory(prefix="wheelcal-rosbag2-", ignore_cleanup_errors=True) as tmp:
        plain = [decompressed_copy(file, Path(tmp)) for file in files]
        scan = _scan_storage(name, plain, info, sink_for)
    # An MCAP storage file is mapped, not read: the mapping outlives the removed copy.
    return dataclasses.replace(scan, path=name) if scan.path != name else scan


def decompressed_copy(file: Path, folder: Path) -> Path:
    """A zstd-compressed storage file (``bag_0.db3.zstd``) decompressed into ``folder``."""
    import zstandard

    target = folder / (file.name[: -len(".zstd")] if file.name.endswith(".zstd") else file.name)
    try:
        with open(file, "rb") as source, open(target, "wb") as sink:
            zstandard.ZstdDecompressor().copy_stream(source, sink)
    except zstandard.ZstdError as exc:
        raise CorruptFileError(
            file, f"a rosbag2 storage file compressed with zstd is damaged ({exc})"
        ) from None
    return target


def _scan_storage(
    name: str, files: list[Path], info: dict, sink_for, zstd_messages: bool = False
) -> McapScan:
    """The scan of a rosbag2's storage files: its one MCAP file, or its SQLite files in order."""
    if str(info.get("storage_identifier")) == "mcap":
        if len(files) != 1:
            raise NotMcapError(name, f"a rosbag2 split into {len(files)} MCAP files: give one")
        return scan_mcap(files[0], sink_for)
    collector = _Rosbag2Collector(name, sink_for, zstd_messages)
    for file in files:
        collector.read(file)
    return McapScan(
        path=name,
        profile="ros2",
        library="rosbag2 (sqlite3)",
        schemas=MappingProxyType(collector.schemas),
        channels=MappingProxyType(collector.channels),
        metadata=(),
        blocks=MappingProxyType({}),
        chunks=0,
        chunks_without_crc=0,
        sinks=MappingProxyType(collector.sinks),
    )


class _Rosbag2Collector:
    """Channels (one per topic name and type), schemas (one per type) and their sinks."""

    def __init__(self, name: str, sink_for, zstd_messages: bool) -> None:
        self.name = name
        self.sink_for = sink_for
        self.zstd_messages = zstd_messages
        self.schemas: dict[int, SchemaRecord] = {}
        self.channels: dict[int, ChannelRecord] = {}
        self.sinks: dict[int, object] = {}
        self._schema_ids: dict[str, int] = {}
        self._channel_ids: dict[tuple[str, str], int] = {}

    def read(self, file: Path) -> None:
        """Read one ``.db3`` file's topics and messages into the channels' sinks."""
        try:
            connection, errors = _connect(file)
        except Exception as exc:  # apsw/sqlite3 open errors
            raise CorruptFileError(
                file, f"cannot be opened as an SQLite database ({exc})"
            ) from None
        try:
            self._read(connection, file)
        except errors as exc:
            raise CorruptFileError(
                file, f"cannot be read as a rosbag2 database: {exc} (a damaged .db3?)"
            ) from None
        finally:
            connection.close()

    def _read(self, connection, file: Path) -> None:
        tables = {row[0] for row in connection.execute("SELECT name FROM sqlite_master")}
        if not {"topics", "messages"} <= tables:
            raise NotMcapError(file, "an SQLite file, but not a rosbag2 (no topics/messages table)")
        definitions = {}
        if "message_definitions" in tables:
            definitions = dict(
                connection.execute(
                    "SELECT topic_type, encoded_message_definition FROM message_definitions"
                ).fetchall()
            )
        topics = connection.execute(
            "SELECT id, name, type, serialization_format FROM topics ORDER BY id"
        ).fetchall()
        counted = []
        for row in topics:
            _check_topic_row(file, row)
            topic_id, topic, type_name, encoding = row
            channel, schema = self._channel(topic, type_name, encoding, definitions)
            sink = self.sinks.get(channel.id)
            if sink is None and self.sink_for is not None:
                sink = self.sink_for(channel, schema)
                if sink is not None:
                    self.sinks[channel.id] = sink
            if sink is None:
                continue
            if getattr(sink, "decodes", True):
                self._feed(connection, file, topic_id, topic, sink)
            else:
                counted.append((topic_id, sink))
        if counted:  # channels no one decodes: their counts only (for listings)
            counts = dict(
                connection.execute(
                    "SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id"
                ).fetchall()
            )
            for topic_id, sink in counted:
                sink.count += int(counts.get(topic_id, 0))

    def _channel(self, topic: str, type_name: str, encoding: str, definitions: dict):
        schema_id = self._schema_ids.get(type_name)
        if schema_id is None:
            schema_id = self._schema_ids[type_name] = len(self._schema_ids) + 1
            text = definitions.get(type_name) or ""
            self.schemas[schema_id] = SchemaRecord(
                schema_id, type_name, "ros2msg", str(text).encode("utf-8")
            )
        key = (topic, type_name)
        channel_id = self._channel_ids.get(key)
        if channel_id is None:
            channel_id = self._channel_ids[key] = len(self._channel_ids) + 1
            self.channels[channel_id] = ChannelRecord(
                channel_id, schema_id, topic, str(encoding), MappingProxyType({})
            )
        return self.channels[channel_id], self.schemas[schema_id]

    def _feed(self, connection, file: Path, topic_id: int, topic: str, sink) -> None:
        """The topic's messages, in batches, as message blocks for ``sink``."""
        rows = iter(
            connection.execute(
                "SELECT id, timestamp, data FROM messages WHERE topic_id = ?", (topic_id,)
            )
        )
        while batch := list(itertools.islice(rows, BATCH_ROWS)):
            try:
                block = self._block(batch, topic)
            except (TypeError, ValueError, OverflowError) as exc:
                if isinstance(exc, CorruptFileError):
                    raise
                raise _bad_cell(file, topic, batch) from None
            sink.add(block)

    def _block(self, batch: list, topic: str) -> MessageBlock:
        n = len(batch)
        log_time = np.fromiter((row[1] for row in batch), np.int64, n)
        data = [row[2] for row in batch]
        if self.zstd_messages or (data and bytes(data[0][:4]) == _ZSTD_MAGIC):
            data = _decompressed(self.name, batch, topic)
        lengths = np.fromiter(map(len, data), np.int64, n)
        offsets = np.zeros(n, np.int64)
        np.cumsum(lengths[:-1], out=offsets[1:])
        return MessageBlock(b"".join(data), offsets, lengths, log_time)


def _check_topic_row(file: Path, row) -> None:
    """A ``topics`` row: an integer id and three text cells (NULL or a blob named)."""
    names = ("id", "name", "type", "serialization_format")
    for index, (name, value) in enumerate(zip(names, row, strict=True)):
        wanted = int if index == 0 else str
        if not isinstance(value, wanted) or isinstance(value, bool):
            raise CorruptFileError(
                file,
                f"the topics table's row with id {row[0]!r}: {name} is "
                f"{_cell_kind(value)}, not {'an integer' if wanted is int else 'text'} "
                "(a damaged .db3, or not written by rosbag2)",
            )


def _cell_kind(value) -> str:
    if value is None:
        return "NULL"
    if isinstance(value, bytes | memoryview):
        return f"a blob of {len(value)} bytes"
    if isinstance(value, str):
        return f"the text {value[:40]!r}"
    return f"the {type(value).__name__} {value!r}"


def _bad_cell(file: Path, topic: str, batch: list) -> CorruptFileError:
    """The first message row of ``batch`` with a cell of the wrong type, named."""
    for row_id, stamp, data in batch:
        if not isinstance(stamp, int) or isinstance(stamp, bool):
            what, cell, wanted = "timestamp", stamp, "an integer (ns)"
        elif not isinstance(data, bytes | memoryview):
            what, cell, wanted = "data", data, "a blob (the serialised message)"
        else:
            continue
        return CorruptFileError(
            file,
            f"the messages table's row with id {row_id!r} (topic {topic!r}): {what} is "
            f"{_cell_kind(cell)}, not {wanted} (a damaged .db3, or not written by rosbag2)",
        )
    return CorruptFileError(file, f"topic {topic!r}: a message row cannot be read")


def _decompressed(name: str, batch: list, topic: str) -> list[bytes]:
    """Messages compressed one by one (rosbag2 ``compression_mode: message``, zstd).

    Bounded as every reader's (:mod:`wheelcal.io.bounded_decompress`): a block
    of messages may decompress to at most the caps of one MCAP chunk of the
    same compressed size, and a frame that declares more is refused before
    anything is allocated.  The common case — a frame that states its size,
    within the budget — is one call; anything else goes the careful way,
    which names the message and what is wrong.
    """
    import zstandard

    budget = limit_bytes(sum(len(row[2]) for row in batch))
    decompressor = zstandard.ZstdDecompressor()
    content_size = zstandard.frame_content_size
    out = []
    for row_id, _, data in batch:
        try:
            size = content_size(data)
            message = decompressor.decompress(data) if 0 <= size <= budget else None
        except zstandard.ZstdError:
            message = None
        if message is None:
            where = f"message row {row_id} (topic {topic!r})"
            message = decompress_unsized(
                name, "zstd", data, budget, where, zstd_decompressor=decompressor
            )
        budget -= len(message)
        out.append(message)
    return out
