"""Read a device recording (MCAP) into a checked :class:`~wheelcal.recording.Recording`.

CONTRACT, "Input: device recordings (MCAP)": the accelerometer topic is found
by its schema —

* ROS 2 ``sensor_msgs/msg/Imu`` (schema encoding ``ros2msg``, messages
  ``cdr``): ``linear_acceleration`` in m/s², time from ``header.stamp`` (the
  message log time only where the stamp is zero);
* ``wheelcal.AccelBatch`` (schema encoding ``jsonschema``, messages
  ``json``): ``{"timestamps_ns": [...], "accel": [[ax, ay, az], ...]}``,
  channel metadata ``unit`` ``m/s^2`` (default) or ``g`` (= 9.80665 m/s²);

— and ``topic=`` chooses among several.  Session facts come from the
``wheelcal.session`` metadata record, overridden by ``info_overrides``.

Optional channels (additive, issue 13), read onto the accelerometer's samples:

* the gyro — ROS 2 ``angular_velocity`` (rad/s; absent where
  ``angular_velocity_covariance[0] == -1``, and a channel of exact zeros is
  absent too), or the batch's ``"gyro"`` rows (channel metadata
  ``gyro_unit`` ``rad/s`` default or ``deg/s``) — kept aligned through the
  accelerometer's repairs and checked by :mod:`~wheelcal.recording.gyro`
  (clipped rows left out as NaN rows);
* the temperature — the batch's ``"temperature_c"``, else a ROS 2
  ``sensor_msgs/msg/Temperature`` topic (the only one, or the one in the
  accelerometer topic's namespace; ``temperature_topic=`` chooses),
  interpolated onto the sample times (:mod:`~wheelcal.recording.temperature`).

The pipeline is: :func:`~wheelcal.io.mcap_scan.scan_mcap` (record walk, every
CRC verified) → a vectorised decoder (:mod:`~wheelcal.io.imu_cdr`,
:mod:`~wheelcal.io.accel_json`) → :meth:`Recording.from_samples
<wheelcal.recording.Recording.from_samples>` (units, the sample checks of
:mod:`~wheelcal.recording.samples`: repairs noted in ``Recording.notes``, or
refusal) → ``Recording`` with times in seconds from the first sample
(``epoch_unix_ns``).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from wheelcal.io.accel_json import (
    ACCEL_BATCH_FORMAT,
    GYRO_UNIT_KEY,
    UNIT_KEY,
    AccelBatchError,
    AccelBatchSink,
    decode_accel_batch,
)
from wheelcal.io.errors import InputError, TopicError
from wheelcal.io.growing import ColumnSink
from wheelcal.io.imu_cdr import IMU_FORMAT, ImuLayoutError, ImuSink, decode_imu_with_gyro
from wheelcal.io.imu_ros1 import ROS1_IMU_FORMAT, decode_ros1_block
from wheelcal.io.mcap_scan import ChannelRecord, McapScan, SchemaRecord
from wheelcal.io.recording_scan import recording_kind, scan_recording
from wheelcal.io.session_meta import SESSION_METADATA_NAME, session_info
from wheelcal.io.temperature_cdr import TEMPERATURE_FORMAT, decode_temperature_blocks
from wheelcal.model import STANDARD_GRAVITY_MPS2
from wheelcal.recording import ACCEL_UNITS, GYRO_UNITS, InputPolicy, Recording, TemperatureReadings

#: The channels the reader takes, by kind, in the order they are tried.
_FORMATS = {
    "ros2": IMU_FORMAT,
    "ros1": ROS1_IMU_FORMAT,  # a ROS 1 bag, or an MCAP written by `mcap convert` from one
    "json": ACCEL_BATCH_FORMAT,
    "temperature": TEMPERATURE_FORMAT,
}
_EXPECTED = f"{IMU_FORMAT}, {ROS1_IMU_FORMAT} or {ACCEL_BATCH_FORMAT}"


@dataclass(frozen=True)
class AccelTopic:
    """An accelerometer channel found in a file."""

    topic: str
    channel_id: int
    encoding: str  # "ros2", "ros1" or "json"
    messages: int
    unit: str  # as the file states it


def _kind(scan: McapScan, channel: ChannelRecord) -> str | None:
    return _kind_of(channel, scan.schema_of(channel))


def _kind_of(channel: ChannelRecord, schema: SchemaRecord | None) -> str | None:
    return next((kind for kind, fmt in _FORMATS.items() if fmt.matches(channel, schema)), None)


class _CountSink:
    """Counts a channel's messages that the reader never decodes (their chunks can go)."""

    #: A bag reader may count these channels' messages without fetching them.
    decodes = False

    def __init__(self) -> None:
        self.count = 0

    def add(self, block) -> None:
        self.count += block.count


class _TemperatureSink(ColumnSink):
    """Decodes a Temperature channel block by block; a decoding error is kept for later."""

    errors = (ImuLayoutError,)

    def decode(self, block, first_message: int) -> dict[str, np.ndarray | None]:
        """One block's stamps, log times and temperatures."""
        stamp, log_time, temp = decode_temperature_blocks((block,), first_message)
        return {"stamp": stamp, "log_time": log_time, "temperature_c": temp}

    def result(self) -> tuple[np.ndarray, ...]:
        columns = self.columns()
        if not columns:
            return np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0)
        return columns["stamp"], columns["log_time"], columns["temperature_c"]


def _sink_for(channel: ChannelRecord, schema: SchemaRecord | None):
    """What consumes a channel's messages during the scan (nothing keeps whole chunks)."""
    kind = _kind_of(channel, schema)
    if kind == "ros2":
        return ImuSink()
    if kind == "ros1":
        return ImuSink(decode_ros1_block)
    if kind == "json":
        return AccelBatchSink()
    if kind == "temperature":
        return _TemperatureSink()
    return _CountSink()


def accel_topics(scan: McapScan) -> list[AccelTopic]:
    """The channels whose schema is one of the contract's accelerometer formats."""
    out = []
    for channel in scan.channels.values():
        kind = _kind(scan, channel)
        if kind not in ("ros2", "ros1", "json"):
            continue
        unit = channel.metadata.get(UNIT_KEY, "m/s^2") if kind == "json" else "m/s^2"
        out.append(
            AccelTopic(channel.topic, channel.id, kind, scan.message_count(channel.id), unit)
        )
    return sorted(out, key=lambda item: item.topic)


def _describe(scan: McapScan) -> str:
    if not scan.channels:
        return "the file has no channels at all"
    parts = []
    for channel in sorted(scan.channels.values(), key=lambda c: c.topic):
        schema = scan.schema_of(channel)
        what = f"{schema.name} ({schema.encoding})" if schema else "no schema"
        parts.append(f"{channel.topic} [{what}, {scan.message_count(channel.id)} messages]")
    return "topics in the file: " + "; ".join(parts)


def choose_topic(scan: McapScan, topic: str | None) -> AccelTopic:
    """The accelerometer channel to read: ``topic`` if given, else the only candidate.

    Raises
    ------
    TopicError
        Unknown topic, a topic of another type, no candidate, or several
        candidates and no choice (the message lists them).
    """
    found = accel_topics(scan)
    if topic is not None:
        matches = [item for item in found if item.topic == topic]
        if len(matches) == 1:
            return matches[0]
        if len(matches) > 1:
            raise TopicError(scan.path, f"topic {topic!r} is defined by several channels")
        if any(channel.topic == topic for channel in scan.channels.values()):
            raise TopicError(
                scan.path,
                f"topic {topic!r} is not an accelerometer topic (need {_EXPECTED}); "
                + _describe(scan),
            )
        raise TopicError(scan.path, f"there is no topic {topic!r}; " + _describe(scan))
    with_data = [item for item in found if item.messages > 0]
    if not with_data:
        raise TopicError(
            scan.path, f"no accelerometer topic (need {_EXPECTED}); " + _describe(scan)
        )
    if len(with_data) > 1:
        listing = ", ".join(
            f"{item.topic} ({item.encoding}, {item.messages} messages)" for item in with_data
        )
        raise TopicError(
            scan.path,
            f"several accelerometer topics: {listing}; choose one (--topic / topic=)",
        )
    return with_data[0]


def list_accel_topics(path: str | os.PathLike) -> list[AccelTopic]:
    """The accelerometer topics of a recording (for a CLI listing)."""
    return accel_topics(scan_recording(path))


@dataclass(frozen=True, eq=False)
class _Decoded:
    """What a decoder gives, in SI units (gyro rad/s), before the checks."""

    time_ns: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray | None
    temperature: tuple[np.ndarray, np.ndarray] | None  # (stamps, °C) on the samples' stamps
    notes: list


def _decode(
    scan: McapScan, chosen: AccelTopic, where: str, gyro: bool, temperature: bool
) -> _Decoded:
    blocks = scan.blocks.get(chosen.channel_id, ())
    sink = scan.sinks.get(chosen.channel_id)
    notes: list[str] = []
    try:
        if chosen.encoding in ("ros2", "ros1"):
            if sink is not None and not blocks:
                stamp, accel, rate = sink.result()
                unstamped = sink.unstamped
            else:
                decoder = decode_ros1_block if chosen.encoding == "ros1" else None
                stamp, log_time, accel, rate = decode_imu_with_gyro(blocks, decoder)
                zero = stamp == 0
                unstamped = int(zero.sum())
                if unstamped:
                    stamp = np.where(zero, log_time, stamp)
            if unstamped:
                notes.append(
                    f"{unstamped} messages had a zero header.stamp; their log time was used"
                )
            return _Decoded(stamp, accel, rate if gyro else None, None, notes)
        if sink is not None and not blocks:
            batch = sink.result(optional=gyro or temperature)
        else:
            batch = decode_accel_batch(blocks, optional=gyro or temperature)
        temp = None
        if temperature and batch.temperature_c is not None:
            temp = (batch.time_ns, batch.temperature_c)
        return _Decoded(batch.time_ns, batch.accel, batch.gyro if gyro else None, temp, notes)
    except (ImuLayoutError, AccelBatchError) as exc:
        raise InputError(scan.path, f"{where}: {exc}") from None


def _gyro_unit(scan: McapScan, chosen: AccelTopic, where: str, override: str | None) -> str:
    unit = override
    if unit is None and chosen.encoding == "json":
        unit = scan.channels[chosen.channel_id].metadata.get(GYRO_UNIT_KEY, "rad/s")
    unit = unit or "rad/s"
    if unit not in GYRO_UNITS:
        raise InputError(scan.path, f"{where}: gyro unit {unit!r} is not one of {list(GYRO_UNITS)}")
    return unit


def temperature_topics(scan: McapScan) -> list[ChannelRecord]:
    """The ROS 2 ``sensor_msgs/msg/Temperature`` channels of a file, by topic."""
    found = [c for c in scan.channels.values() if _kind(scan, c) == "temperature"]
    return sorted(found, key=lambda c: c.topic)


def _temperature_topic(
    scan: McapScan, accel_topic: str, wanted: str | None, notes: list[str]
) -> tuple[ChannelRecord, np.ndarray, np.ndarray] | None:
    """The Temperature topic to read and its (stamps, °C), or None (with a note if unclear)."""
    found = temperature_topics(scan)
    if wanted is not None:
        chosen = [c for c in found if c.topic == wanted]
        if not chosen:
            listing = ", ".join(c.topic for c in found) or "none"
            raise TopicError(
                scan.path,
                f"there is no sensor_msgs/msg/Temperature topic {wanted!r} "
                f"(temperature topics: {listing})",
            )
    else:
        chosen = [c for c in found if scan.message_count(c.id) > 0]
        if len(chosen) > 1:
            space = accel_topic.rsplit("/", 1)[0] + "/"
            chosen = [c for c in chosen if c.topic.startswith(space)] if space != "/" else []
            if len(chosen) != 1:
                listing = ", ".join(c.topic for c in found)
                notes.append(
                    f"several temperature topics ({listing}); none read — choose one "
                    "(temperature_topic=)"
                )
                return None
    if not chosen:
        return None
    channel = chosen[0]
    try:
        sink = scan.sinks.get(channel.id)
        if sink is not None and not scan.blocks.get(channel.id):
            stamp, log_time, temp = sink.result()
        else:
            stamp, log_time, temp = decode_temperature_blocks(scan.blocks.get(channel.id, ()))
    except ImuLayoutError as exc:
        raise InputError(scan.path, f"topic {channel.topic}: {exc}") from None
    if stamp.size == 0:
        return None
    stamp = np.where(stamp == 0, log_time, stamp)
    return channel, stamp, temp


def read_recording(
    path: str | os.PathLike,
    topic: str | None = None,
    info_overrides: Mapping[str, object] | None = None,
    *,
    info_defaults: Mapping[str, object] | None = None,
    accel_unit: str | None = None,
    policy: InputPolicy | None = None,
    gravity_checked: bool = True,
    gyro: bool = True,
    gyro_unit: str | None = None,
    temperature: bool = True,
    temperature_topic: str | None = None,
) -> Recording:
    """Read the accelerometer samples and session facts of a recording.

    Parameters
    ----------
    path:
        The recording: MCAP, a rosbag2 or ROS 1 bag, or a CSV export whose format
        states its units (:func:`~wheelcal.io.csv_recording.read_csv_recording`,
        which takes the same options; a CSV has no topics).
    topic:
        The accelerometer topic; ``None`` picks the only one there is.
    info_overrides:
        Session facts that replace the file's (``radius_m``, ``radius_std_m``,
        ``sensor_id``, ``mounting_id``, ``gravity_mps2``, ``full_scale_g``);
        ``None`` values are ignored, unknown keys are an error.
    info_defaults:
        Session facts used where neither the file nor ``info_overrides``
        gives one (a pipeline file's defaults); same keys.
    accel_unit:
        Override of the unit the file states (``"m/s^2"`` or ``"g"``), for
        files that misstate it.
    policy:
        Thresholds for repairing versus refusing defects
        (:class:`~wheelcal.recording.samples.InputPolicy`).
    gravity_checked:
        Refuse a ``gravity_mps2`` outside Earth's 9.7–9.9 m/s² (False: the
        user forced it).
    gyro:
        Read the gyroscope if the file has one (``False``: accelerometer only).
    gyro_unit:
        Override of the gyro unit the file states (``"rad/s"`` or ``"deg/s"``;
        JSON: channel metadata ``gyro_unit``, ROS 2: rad/s by REP 103).
    temperature:
        Read the temperature if the file has one.
    temperature_topic:
        The ``sensor_msgs/msg/Temperature`` topic, when a file has several.

    Returns
    -------
    Recording
        Times in s from the first sample (``epoch_unix_ns``), samples in m/s²,
        ``source`` = the path, ``topic``, and ``notes`` on anything repaired.
        ``gyro_radps`` (rad/s, NaN rows left out) and ``temperature_c`` when
        the file has them.  ``info.radius_m`` may be ``None`` — see
        :func:`~wheelcal.io.session_meta.require_radius`.

    Raises
    ------
    InputError
        (and its subclasses ``NotMcapError``, ``CorruptFileError``,
        ``TopicError``, ``MetadataError``, ``SampleError``) with the file
        and the problem in the message.
    """
    if gyro_unit is not None and gyro_unit not in GYRO_UNITS:
        raise InputError(path, f"gyro unit {gyro_unit!r} is not one of {list(GYRO_UNITS)}")
    if recording_kind(path) == "csv":
        if temperature_topic is not None:
            raise TopicError(path, "a CSV log has no topics (temperature_topic given)")
        from wheelcal.io.csv_recording import read_csv_recording

        return read_csv_recording(
            path,
            topic,
            info_overrides,
            info_defaults=info_defaults,
            accel_unit=accel_unit,
            policy=policy,
            gravity_checked=gravity_checked,
            gyro=gyro,
            gyro_unit=gyro_unit,
            temperature=temperature,
        )
    scan = scan_recording(path, sink_for=_sink_for)
    chosen = choose_topic(scan, topic)
    where = f"topic {chosen.topic}"
    records = [dict(values) for name, values in scan.metadata if name == SESSION_METADATA_NAME]
    info = session_info(
        scan.path, records, info_overrides, info_defaults, gravity_forced=not gravity_checked
    )
    unit = accel_unit or chosen.unit
    if unit not in ACCEL_UNITS:
        raise InputError(scan.path, f"{where}: unit {unit!r} is not one of {list(ACCEL_UNITS)}")
    samples = _samples_of(scan, chosen, unit, gyro, gyro_unit, temperature, temperature_topic)
    if accel_unit is not None and accel_unit != chosen.unit:  # the option claims the unit
        samples.update(_override_wording(chosen, accel_unit))
    del scan  # the decoded columns are all that is left of the file
    # The decoded columns are ours to give away: converted and kept in place, no copy.
    return Recording.from_samples(**samples, info=info, policy=policy, consume=True)


@dataclass(frozen=True, eq=False)
class RawImuSamples:
    """Every message of an accelerometer topic as the file has it, before any check.

    Stamps (int ns, file order), samples in m/s² (``g`` converted), the gyro in rad/s
    (``None`` without one); ``source_format`` is the container (``mcap``, ``ros1 bag``,
    ``rosbag2``), ``encoding`` the channel's (``ros2``, ``ros1``, ``json``).
    """

    source: str
    topic: str
    encoding: str
    source_format: str
    time_ns: np.ndarray
    accel_mps2: np.ndarray
    gyro_radps: np.ndarray | None


def read_raw_samples(
    path: str | os.PathLike,
    topic: str | None = None,
    *,
    accel_unit: str | None = None,
    gyro_unit: str | None = None,
) -> RawImuSamples:
    """Every sample of an accelerometer topic, unchecked: what ``wheelcal apply`` corrects.

    The same scan, topic choice and decoders as :func:`read_recording` (every format it
    reads), without the repairs: nothing is dropped, merged or sorted, so each message
    in has its sample out (the checked :func:`read_recording` says which it would leave
    out, and why).
    """
    scan = scan_recording(path, sink_for=_sink_for)
    chosen = choose_topic(scan, topic)
    where = f"topic {chosen.topic}"
    decoded = _decode(scan, chosen, where, gyro=True, temperature=False)
    unit = accel_unit or chosen.unit
    if unit not in ACCEL_UNITS:
        raise InputError(scan.path, f"{where}: unit {unit!r} is not one of {list(ACCEL_UNITS)}")
    accel = np.asarray(decoded.accel, dtype=float)
    if unit == "g":
        accel = accel * STANDARD_GRAVITY_MPS2
    gyro = decoded.gyro
    if gyro is not None:
        gyro = np.asarray(gyro, dtype=float)
        if _gyro_unit(scan, chosen, where, gyro_unit) == "deg/s":
            gyro = np.radians(gyro)
    return RawImuSamples(
        source=scan.path,
        topic=chosen.topic,
        encoding=chosen.encoding,
        source_format=_container(scan),
        time_ns=np.asarray(decoded.time_ns, dtype=np.int64),
        accel_mps2=accel,
        gyro_radps=gyro,
    )


def _container(scan: McapScan) -> str:
    """``mcap``, ``ros1 bag`` or ``rosbag2``: which container the scan read."""
    library = scan.library.lower()
    if library.startswith("rosbag2"):
        return "rosbag2"
    if "rosbag" in library or "ros1 bag" in library:
        return "ros1 bag"
    return "mcap"


def _samples_of(
    scan: McapScan,
    chosen: AccelTopic,
    unit: str,
    gyro: bool,
    gyro_unit: str | None,
    temperature: bool,
    temperature_topic: str | None,
) -> dict[str, object]:
    """The file's part of :meth:`Recording.from_samples`' arguments: decoded columns, notes."""
    where = f"topic {chosen.topic}"
    decoded = _decode(scan, chosen, where, gyro, temperature)
    notes = decoded.notes
    stated_gyro_unit = "rad/s"
    if decoded.gyro is not None:
        stated_gyro_unit = _gyro_unit(scan, chosen, where, gyro_unit)
    readings = None
    if temperature:
        readings = _temperature_source(scan, chosen, decoded, temperature_topic, notes)
    if scan.chunks_without_crc:
        notes.append(
            f"{scan.chunks_without_crc} of {scan.chunks} chunks carry no CRC; "
            "their integrity could not be verified"
        )
    return {
        "source": scan.path,
        "time_ns": decoded.time_ns,
        "accel": decoded.accel,
        "unit": unit,
        "gyro": decoded.gyro,
        "gyro_unit": stated_gyro_unit,
        "temperature": readings,
        "topic": chosen.topic,
        "notes": notes,
        "label": f"{scan.path} ({where})",
        "unit_remedy": _unit_remedy(chosen, unit),
        "gyro_unit_hint": _gyro_unit_hint(chosen),
    }


def _override_wording(chosen: AccelTopic, accel_unit: str) -> dict[str, str]:
    """Who claimed the unit and how to fix it, when ``accel_unit`` overrode the file's."""
    own = "m/s^2 (REP 103)" if chosen.encoding in ("ros2", "ros1") else repr(chosen.unit)
    return {
        "unit_stated_by": f"--accel-unit {accel_unit} (Python: accel_unit={accel_unit!r})",
        "unit_remedy": f"leave --accel-unit out (accel_unit=None): the file's own unit is {own}",
    }


def _unit_remedy(chosen: AccelTopic, unit: str) -> str:
    """How to state the right accelerometer unit for this file's format."""
    other = "m/s^2" if unit == "g" else "g"
    if chosen.encoding in ("ros2", "ros1"):
        return (
            f"read it with --accel-unit {other} (Python: accel_unit={other!r}); "
            "sensor_msgs/msg/Imu carries m/s² by REP 103, so the driver that wrote "
            "this file should be fixed"
        )
    return (
        f"state the unit: --accel-unit {other} on the command line (Python: "
        f"accel_unit={other!r}), or the channel's metadata unit ('g' or 'm/s^2') in the file"
    )


def _gyro_unit_hint(chosen: AccelTopic) -> str:
    """How to state the right gyro unit for this file's format."""
    if chosen.encoding == "json":
        return "state the channel metadata gyro_unit ('rad/s' or 'deg/s')"
    return (
        "sensor_msgs/msg/Imu carries rad/s (REP 103): fix the driver, or read with "
        "gyro_unit='deg/s'"
    )


def _temperature_source(
    scan: McapScan, chosen: AccelTopic, decoded: _Decoded, wanted: str | None, notes: list[str]
) -> TemperatureReadings | None:
    """The temperature readings to use: the batch's own, else a topic's."""
    if decoded.temperature is not None:
        if wanted is not None:
            notes.append(f"temperature from the batches' temperature_c; topic {wanted} not used")
        stamps, values = decoded.temperature
        return TemperatureReadings("temperature_c of the batches", stamps, values)
    if not temperature_topics(scan):
        if wanted is not None:
            raise TopicError(scan.path, f"there is no sensor_msgs/msg/Temperature topic {wanted!r}")
        return None
    found = _temperature_topic(scan, chosen.topic, wanted, notes)
    if found is None:
        return None
    channel, stamps, values = found
    return TemperatureReadings(f"topic {channel.topic}", stamps, values)
