"""Write recordings to MCAP (contract formats), and copy an MCAP adding channels.

Both writers go through :func:`~wheelcal.io.atomic.atomic_output`: the file
appears complete or not at all.  Files carry chunk CRCs *and* the data-section
CRC, so :func:`~wheelcal.io.mcap_reader.read_recording` can prove they are
intact.

* :func:`write_recording` — a :class:`~wheelcal.recording.Recording` as ROS 2
  ``sensor_msgs/msg/Imu`` (one message per sample) or ``wheelcal.AccelBatch``
  JSON (``batch_size`` samples per message), with the ``wheelcal.session``
  metadata record.  A gyro goes into ``angular_velocity`` (ROS 2; a left-out
  row is marked absent, covariance[0] = −1) or the batch's ``"gyro"`` rows
  (JSON; ``null``); a temperature into a ``sensor_msgs/msg/Temperature``
  topic (ROS 2) or the batch's ``"temperature_c"`` (JSON).
* :func:`write_accel_mcap` — the same from raw arrays, without the checks a
  ``Recording`` makes (for converters, and for test files with defects).
* :func:`copy_with_channels` — every record of an existing MCAP (schemas,
  channels, messages with their sequence and publish time, metadata,
  attachments) plus new channels and metadata, e.g. a calibrated
  accelerometer topic for ``wheelcal apply``.
"""

from __future__ import annotations

import heapq
import json
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from wheelcal.io.accel_json import (
    ACCEL_BATCH_FORMAT,
    GYRO_UNIT_KEY,
    UNIT_KEY,
    encode_accel_batches,
)
from wheelcal.io.atomic import atomic_output
from wheelcal.io.channel_format import ChannelFormat
from wheelcal.io.errors import CorruptFileError
from wheelcal.io.imu_cdr import IMU_FORMAT, encode_imu_messages
from wheelcal.io.mcap_scan import scan_mcap
from wheelcal.io.ownership import MARK_RECORD
from wheelcal.io.session_meta import SESSION_METADATA_NAME
from wheelcal.io.temperature_cdr import TEMPERATURE_FORMAT, encode_temperature_messages
from wheelcal.recording import ACCEL_UNITS, GYRO_UNITS, Recording, SessionInfo

DEFAULT_TOPICS = {"ros2": "/imu/data_raw", "json": "/wheelcal/accel"}
DEFAULT_TEMPERATURE_TOPIC = "/imu/temperature"
DEFAULT_CHUNK_BYTES = 1024 * 1024
#: Samples encoded at a time: the writer holds this many messages, not the whole file's.
PIECE_SAMPLES = 8192

Encoding = Literal["ros2", "json"]
Compression = Literal["zstd", "lz4", "none"]


class EncodedMessages(Sequence):
    """``(log_time_ns, payload)`` pairs encoded piece by piece as they are iterated.

    A long recording's messages (≈ 330 B per ROS 2 Imu sample) never sit in
    memory at once: ``encode(start, stop)`` gives the messages of samples
    ``start:stop``, asked for :data:`PIECE_SAMPLES` samples (rounded to whole
    messages) at a time, so writing holds one piece.  Indexing encodes the
    whole sequence (for tests and small channels).
    """

    def __init__(
        self,
        encode: Callable[[int, int], list[tuple[int, bytes]]],
        samples: int,
        per_message: int = 1,
    ) -> None:
        self._encode = encode
        self._samples = samples
        self._per_message = per_message

    def __len__(self) -> int:
        return -(-self._samples // self._per_message)

    def __iter__(self) -> Iterator[tuple[int, bytes]]:
        step = max(1, PIECE_SAMPLES // self._per_message) * self._per_message
        for start in range(0, self._samples, step):
            yield from self._encode(start, min(start + step, self._samples))

    def __getitem__(self, index):
        return list(self)[index]


@dataclass(frozen=True, eq=False)
class ChannelData:
    """A channel to write: its schema, encoding, metadata and messages.

    ``messages`` holds ``(log_time_ns, payload)`` pairs (a tuple, or
    :class:`EncodedMessages` encoded as they are written); the publish time is
    the log time.
    """

    topic: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes = field(repr=False)
    message_encoding: str
    messages: Sequence[tuple[int, bytes]] = field(repr=False)
    metadata: Mapping[str, str] = field(default_factory=dict)

    @classmethod
    def of(
        cls,
        fmt: ChannelFormat,
        topic: str,
        messages: Sequence[tuple[int, bytes]],
        metadata: Mapping[str, str] | None = None,
    ) -> ChannelData:
        """A channel of the format ``fmt`` (its schema stored with it)."""
        return cls(
            topic=topic,
            schema_name=fmt.schema_name,
            schema_encoding=fmt.schema_encoding,
            schema_data=fmt.schema_data,
            message_encoding=fmt.message_encoding,
            messages=messages,
            metadata={} if metadata is None else metadata,
        )


def session_metadata(info: SessionInfo) -> dict[str, str]:
    """The ``wheelcal.session`` key-value strings for ``info`` (CONTRACT, input item 3).

    Floats are written with ``repr`` so they read back exactly; unset optional
    facts are left out.
    """
    out: dict[str, str] = {}
    if info.radius_m is not None:
        out["radius_m"] = repr(float(info.radius_m))
    out["radius_std_m"] = repr(float(info.radius_std_m))
    if info.sensor_id:
        out["sensor_id"] = info.sensor_id
    if info.mounting_id:
        out["mounting_id"] = info.mounting_id
    if info.gravity_mps2 is not None:
        out["gravity_mps2"] = repr(float(info.gravity_mps2))
    if info.full_scale_g is not None:
        out["full_scale_g"] = repr(float(info.full_scale_g))
    if info.gyro_full_scale_dps is not None:
        out["gyro_full_scale_dps"] = repr(float(info.gyro_full_scale_dps))
    for key, value in info.extra:
        out.setdefault(key, value)
    return out


def accel_channel(
    time_ns: np.ndarray,
    accel: np.ndarray,
    *,
    encoding: Encoding = "ros2",
    topic: str | None = None,
    batch_size: int = 1,
    frame_id: str = "imu",
    unit: str = "m/s^2",
    gyro: np.ndarray | None = None,
    gyro_unit: str = "rad/s",
    temperature_c: np.ndarray | None = None,
    accel_covariance_mps2sq: np.ndarray | None = None,
) -> ChannelData:
    """An accelerometer channel (with an optional gyro) in one of the contract's encodings.

    Parameters
    ----------
    time_ns:
        Sample stamps, integer nanoseconds since the Unix epoch.
    accel:
        Samples (N, 3) in ``unit``.
    encoding:
        ``"ros2"`` (``sensor_msgs/msg/Imu``, CDR, one message per sample; the
        unit must be m/s², REP 103) or ``"json"`` (``wheelcal.AccelBatch``).
    topic:
        Defaults to ``/imu/data_raw`` (ros2) or ``/wheelcal/accel`` (json).
    batch_size:
        Samples per JSON message.
    frame_id:
        ``header.frame_id`` of the Imu messages.
    unit:
        ``"m/s^2"`` or ``"g"`` (JSON only), stored in the channel metadata.
    gyro:
        Angular rate (N, 3) in ``gyro_unit``, or ``None``; NaN rows are
        written as "no reading" (ROS 2: covariance[0] = −1; JSON: ``null``).
    gyro_unit:
        ``"rad/s"`` or ``"deg/s"`` (JSON only; stored as ``gyro_unit``).
    temperature_c:
        Per-sample temperature (N,) in °C — JSON only (``"temperature_c"``);
        ROS 2 carries it on its own topic (:func:`temperature_channel`).
    accel_covariance_mps2sq:
        The samples' noise covariance (3, 3) in (m/s²)², written as every ROS 2
        message's ``linear_acceleration_covariance`` (``None``: zeros, unknown);
        JSON stores it as the channel metadata ``accel_covariance_mps2sq``.
    """
    if unit not in ACCEL_UNITS:
        raise ValueError(f"unit must be one of {ACCEL_UNITS}, got {unit!r}")
    if gyro_unit not in GYRO_UNITS:
        raise ValueError(f"gyro_unit must be one of {GYRO_UNITS}, got {gyro_unit!r}")
    time_ns = np.asarray(time_ns, dtype=np.int64).reshape(-1)
    accel = np.asarray(accel, dtype=float).reshape(-1, 3)
    if time_ns.size != accel.shape[0]:
        raise ValueError(f"{time_ns.size} stamps but {accel.shape[0]} samples")
    if encoding == "ros2":
        if unit != "m/s^2":
            raise ValueError("sensor_msgs/msg/Imu carries m/s² only (REP 103)")
        if gyro is not None and gyro_unit != "rad/s":
            raise ValueError("sensor_msgs/msg/Imu carries rad/s only (REP 103)")
        if temperature_c is not None:
            raise ValueError(
                "ROS 2 carries the temperature on its own topic: temperature_channel()"
            )
        if gyro is not None:
            gyro = np.asarray(gyro, dtype=float).reshape(-1, 3)

        def imu(start: int, stop: int) -> list[tuple[int, bytes]]:
            rate = None if gyro is None else gyro[start:stop]
            stamps = time_ns[start:stop]
            payloads = encode_imu_messages(
                stamps, accel[start:stop], frame_id, rate, accel_covariance_mps2sq
            )
            return list(zip(stamps.tolist(), payloads, strict=True))

        messages = EncodedMessages(imu, time_ns.size)
        return ChannelData.of(IMU_FORMAT, topic or DEFAULT_TOPICS["ros2"], messages)
    if encoding == "json":
        metadata = {UNIT_KEY: unit}
        if gyro is not None:
            metadata[GYRO_UNIT_KEY] = gyro_unit
        if accel_covariance_mps2sq is not None:
            cov = np.asarray(accel_covariance_mps2sq, dtype=float).reshape(3, 3)
            metadata["accel_covariance_mps2sq"] = json.dumps(cov.tolist())
        if batch_size < 1:
            raise ValueError(f"batch_size must be at least 1, got {batch_size}")
        if gyro is not None and np.shape(gyro)[0] != time_ns.size:
            raise ValueError(f"{time_ns.size} stamps but {np.shape(gyro)[0]} gyro rows")
        if temperature_c is not None and np.size(temperature_c) != time_ns.size:
            raise ValueError(f"{time_ns.size} stamps but {np.size(temperature_c)} temperatures")

        def batches(start: int, stop: int) -> list[tuple[int, bytes]]:
            rate = None if gyro is None else np.asarray(gyro)[start:stop]
            temp = None if temperature_c is None else np.asarray(temperature_c)[start:stop]
            return encode_accel_batches(
                time_ns[start:stop], accel[start:stop], batch_size, rate, temp
            )

        messages = EncodedMessages(batches, time_ns.size, batch_size)
        return ChannelData.of(
            ACCEL_BATCH_FORMAT, topic or DEFAULT_TOPICS["json"], messages, metadata
        )
    raise ValueError(f"encoding must be 'ros2' or 'json', got {encoding!r}")


def temperature_channel(
    time_ns: np.ndarray,
    temperature_c: np.ndarray,
    *,
    topic: str = DEFAULT_TEMPERATURE_TOPIC,
    stride: int = 1,
    frame_id: str = "imu",
) -> ChannelData:
    """A ROS 2 ``sensor_msgs/msg/Temperature`` channel: every ``stride``-th reading.

    NaN readings are skipped (a Temperature message has no "absent" marker).
    """
    if stride < 1:
        raise ValueError(f"stride must be at least 1, got {stride}")
    time_ns = np.asarray(time_ns, dtype=np.int64).reshape(-1)[::stride]
    temp = np.asarray(temperature_c, dtype=float).reshape(-1)[::stride]
    keep = np.isfinite(temp)
    time_ns, temp = time_ns[keep], temp[keep]

    def readings(start: int, stop: int) -> list[tuple[int, bytes]]:
        payloads = encode_temperature_messages(time_ns[start:stop], temp[start:stop], frame_id)
        return list(zip(time_ns[start:stop].tolist(), payloads, strict=True))

    return ChannelData.of(TEMPERATURE_FORMAT, topic, EncodedMessages(readings, time_ns.size))


def _compression(name: str):
    from mcap.writer import CompressionType

    table = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
    try:
        return table[name]
    except KeyError:
        raise ValueError(f"compression must be one of {sorted(table)}, got {name!r}") from None


def _new_writer(stream, compression: str, chunk_bytes: int):
    from mcap.writer import Writer

    return Writer(
        stream,
        chunk_size=chunk_bytes,
        compression=_compression(compression),
        enable_crcs=True,
        enable_data_crcs=True,
    )


def write_channels(
    path: str | os.PathLike,
    channels: Sequence[ChannelData],
    metadata: Mapping[str, Mapping[str, str]] | None = None,
    *,
    profile: str = "",
    compression: Compression = "zstd",
    chunk_bytes: int = DEFAULT_CHUNK_BYTES,
    replace: bool = True,
) -> None:
    """Write channels and metadata records to a new MCAP file, atomically.

    Channels are merged by log time; each channel keeps its own message order.
    ``replace=False`` refuses an existing ``path``
    (:class:`~wheelcal.io.atomic.OutputExistsError`).
    """
    _compression(compression)  # fail before creating anything
    with atomic_output(path, replace=replace) as stream:
        writer = _new_writer(stream, compression, chunk_bytes)
        writer.start(profile=profile, library=_library())
        ids = [_register(writer, channel) for channel in channels]
        _write_messages(writer, [], channels, ids)
        for name, values in (metadata or {}).items():
            writer.add_metadata(name, dict(values))
        writer.finish()


def _library() -> str:
    from wheelcal import __version__

    return f"wheelcal/{__version__}"


def _register(writer, channel: ChannelData) -> int:
    schema_id = writer.register_schema(
        channel.schema_name, channel.schema_encoding, channel.schema_data
    )
    return writer.register_channel(
        channel.topic, channel.message_encoding, schema_id, dict(channel.metadata)
    )


def _write_messages(writer, originals: list, channels: Sequence[ChannelData], ids: list) -> None:
    """Originals ``(log, channel, seq, publish, data)`` and new channels, merged by log time.

    A merge, not a sort: each sequence keeps its own order, so a writer never
    silently repairs data given out of order (the reader reports that).
    """
    sequences = [originals]
    for channel_id, channel in zip(ids, channels, strict=True):
        sequences.append(_records(channel_id, channel.messages))  # lazily: piece by piece
    for log, channel_id, sequence, publish, data in heapq.merge(
        *sequences, key=lambda item: item[0]
    ):
        writer.add_message(
            channel_id=channel_id,
            log_time=log,
            data=data,
            publish_time=publish,
            sequence=sequence,
        )


def _records(channel_id: int, messages: Sequence[tuple[int, bytes]]):
    """``(log, channel, sequence 0, publish = log, data)`` of a channel's messages, lazily."""
    for log, data in messages:
        yield log, channel_id, 0, log, data


def write_accel_mcap(
    path: str | os.PathLike,
    time_ns: np.ndarray,
    accel: np.ndarray,
    *,
    info: SessionInfo | None = None,
    encoding: Encoding = "ros2",
    topic: str | None = None,
    batch_size: int = 1,
    unit: str = "m/s^2",
    frame_id: str = "imu",
    compression: Compression = "zstd",
    session: Mapping[str, str] | None = None,
    gyro: np.ndarray | None = None,
    gyro_unit: str = "rad/s",
    temperature_c: np.ndarray | None = None,
    temperature_stride: int = 1,
    replace: bool = True,
    metadata: Mapping[str, Mapping[str, str]] | None = None,
) -> None:
    """Write raw stamps and samples as a contract MCAP (no validation of the data).

    Parameters
    ----------
    path:
        Output file (written atomically).
    time_ns, accel:
        Stamps (int ns since the Unix epoch) and samples (N, 3) in ``unit``.
    info:
        Session facts for the ``wheelcal.session`` record.
    session:
        Raw ``wheelcal.session`` strings, written as given (overrides ``info``
        key by key) — lets converters pass values through and tests write bad ones.
    encoding, topic, batch_size, unit, frame_id:
        See :func:`accel_channel`.
    compression:
        ``"zstd"``, ``"lz4"`` or ``"none"``.
    gyro, gyro_unit:
        Optional angular rate (N, 3) and its unit (ROS 2: rad/s only).
    temperature_c, temperature_stride:
        Optional per-sample temperature (N,), °C: the batches' ``temperature_c``
        (JSON), or a ``sensor_msgs/msg/Temperature`` topic (ROS 2) with every
        ``temperature_stride``-th reading.
    replace:
        ``False`` refuses an existing ``path``
        (:class:`~wheelcal.io.atomic.OutputExistsError`).
    metadata:
        More metadata records, ``{name: {key: value}}`` (e.g. the
        ``wheelcal.output`` mark of :mod:`wheelcal.io.ownership`).
    """
    ros2 = encoding == "ros2"
    channels = [
        accel_channel(
            time_ns,
            accel,
            encoding=encoding,
            topic=topic,
            batch_size=batch_size,
            frame_id=frame_id,
            unit=unit,
            gyro=gyro,
            gyro_unit=gyro_unit,
            temperature_c=None if ros2 else temperature_c,
        )
    ]
    if ros2 and temperature_c is not None:
        channels.append(
            temperature_channel(
                time_ns, temperature_c, stride=temperature_stride, frame_id=frame_id
            )
        )
    values = session_metadata(info) if info is not None else {}
    values.update(session or {})
    records = {SESSION_METADATA_NAME: values} if values else {}
    records.update(metadata or {})
    write_channels(
        path,
        channels,
        records or None,
        profile="ros2" if encoding == "ros2" else "",
        compression=compression,
        replace=replace,
    )


def recording_stamps_ns(recording: Recording) -> np.ndarray:
    """Absolute sample stamps (int ns since the Unix epoch) of a recording."""
    return recording.epoch_unix_ns + np.rint(recording.time_s * 1e9).astype(np.int64)


def write_recording(
    recording: Recording,
    path: str | os.PathLike,
    *,
    encoding: Encoding = "ros2",
    topic: str | None = None,
    batch_size: int = 1,
    frame_id: str = "imu",
    compression: Compression = "zstd",
    temperature_stride: int = 1,
    replace: bool = True,
    metadata: Mapping[str, Mapping[str, str]] | None = None,
) -> None:
    """Write a recording as a contract MCAP with its ``wheelcal.session`` record.

    Samples are written in m/s², the gyro (if any) in rad/s; stamps are
    ``epoch_unix_ns + round(time_s · 1e9)``.

    Parameters
    ----------
    recording:
        What to write.
    path:
        Output file (written atomically: complete or absent).
    encoding:
        ``"ros2"`` — ``sensor_msgs/msg/Imu``, one CDR message per sample;
        ``"json"`` — ``wheelcal.AccelBatch``, ``batch_size`` samples per message.
    topic, batch_size, frame_id:
        See :func:`accel_channel`.
    compression:
        Chunk compression: ``"zstd"``, ``"lz4"`` or ``"none"``.
    temperature_stride:
        ROS 2 only: write every n-th temperature reading to the
        ``sensor_msgs/msg/Temperature`` topic (a driver publishes it slower
        than the samples; the reader interpolates).
    replace, metadata:
        As :func:`write_accel_mcap`.
    """
    write_accel_mcap(
        path,
        recording_stamps_ns(recording),
        recording.accel_mps2,
        info=recording.info,
        encoding=encoding,
        topic=topic or recording.topic or None,
        batch_size=batch_size,
        frame_id=frame_id,
        compression=compression,
        gyro=recording.gyro_radps,
        temperature_c=recording.temperature_c,
        temperature_stride=temperature_stride,
        replace=replace,
        metadata=metadata,
    )


def copy_with_channels(
    source: str | os.PathLike,
    destination: str | os.PathLike,
    channels: Sequence[ChannelData],
    metadata: Mapping[str, Mapping[str, str]] | None = None,
    *,
    compression: Compression = "zstd",
    chunk_bytes: int = DEFAULT_CHUNK_BYTES,
    replace: bool = True,
) -> None:
    """Copy an MCAP file, keeping every record, and add channels and metadata.

    Schemas, channels (with their metadata), messages (with sequence numbers
    and publish times), metadata records and attachments of ``source`` are
    all kept; ``channels`` are added, merged in by log time.  The source is
    verified first (CRCs, truncation), so a damaged source is an error, not a
    damaged copy.

    Parameters
    ----------
    source:
        Existing MCAP file.
    destination:
        New file (written atomically; may not be ``source`` itself).
    channels:
        Channels to add, e.g. from :func:`accel_channel`.  A topic that
        already exists in ``source`` is refused.
    metadata:
        Metadata records to add, ``{name: {key: value}}``.
    compression, chunk_bytes:
        Chunk compression and size of the copy.
    replace:
        ``False`` refuses an existing ``destination``
        (:class:`~wheelcal.io.atomic.OutputExistsError`).
    """
    if os.path.abspath(source) == os.path.abspath(destination):
        raise ValueError(f"{destination}: the copy must not overwrite its source")
    scan = scan_mcap(source)  # clear errors for damaged or non-MCAP sources
    existing = {channel.topic for channel in scan.channels.values()}
    for channel in channels:
        if channel.topic in existing:
            raise ValueError(f"{source}: topic {channel.topic!r} already exists; choose another")
        existing.add(channel.topic)
    _compression(compression)
    with atomic_output(destination, replace=replace) as stream:
        writer = _new_writer(stream, compression, chunk_bytes)
        writer.start(profile=scan.profile, library=scan.library)
        originals, attachments, metadata_records = _copy_definitions(source, writer)
        ids = [_register(writer, channel) for channel in channels]
        _write_messages(writer, originals, channels, ids)
        for att in attachments:
            writer.add_attachment(att.create_time, att.log_time, att.name, att.media_type, att.data)
        for record in metadata_records:
            writer.add_metadata(record.name, dict(record.metadata))
        for name, values in (metadata or {}).items():
            writer.add_metadata(name, dict(values))
        writer.finish()


def _copy_definitions(source, writer) -> tuple[list, list, list]:
    """``source``'s schemas and channels registered with ``writer``; its other records.

    Returns the messages as ``(log, new channel id, sequence, publish, data)``,
    the attachments and the metadata records, in file order, for the caller
    to write after its own channels are registered.
    """
    from mcap.exceptions import McapError
    from mcap.records import Attachment, Channel, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader

    schema_ids: dict[int, int] = {0: 0}
    channel_ids: dict[int, int] = {}
    originals, attachments, metadata_records = [], [], []
    try:
        with open(source, "rb") as src:
            for record in StreamReader(src, validate_crcs=True).records:
                if isinstance(record, Schema) and record.id not in schema_ids:
                    schema_ids[record.id] = writer.register_schema(
                        record.name, record.encoding, record.data
                    )
                elif isinstance(record, Channel) and record.id not in channel_ids:
                    channel_ids[record.id] = writer.register_channel(
                        record.topic,
                        record.message_encoding,
                        schema_ids[record.schema_id],
                        dict(record.metadata),
                    )
                elif isinstance(record, Message):
                    originals.append(
                        (
                            record.log_time,
                            channel_ids[record.channel_id],
                            record.sequence,
                            record.publish_time,
                            record.data,
                        )
                    )
                elif isinstance(record, Attachment):
                    attachments.append(record)
                elif isinstance(record, Metadata) and record.name != MARK_RECORD:
                    metadata_records.append(record)  # the copy gets its own mark
    except (McapError, KeyError, EOFError) as exc:
        raise CorruptFileError(source, f"cannot be copied: {exc}") from None
    return originals, attachments, metadata_records
