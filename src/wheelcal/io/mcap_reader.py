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

The pipeline is: :func:`~wheelcal.io.mcap_scan.scan_mcap` (record walk, every
CRC verified) → a vectorised decoder (:mod:`~wheelcal.io.imu_cdr`,
:mod:`~wheelcal.io.accel_json`) → :func:`~wheelcal.io.sample_checks.clean_samples`
(repairs noted in ``Recording.notes``, or refusal) → ``Recording`` with times
in seconds from the first sample (``epoch_unix_ns``).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from wheelcal.io.accel_json import (
    ACCEL_BATCH_SCHEMA_NAME,
    JSON_MESSAGE_ENCODING,
    JSON_SCHEMA_ENCODING,
    UNIT_KEY,
    UNITS,
    AccelBatchError,
    decode_accel_blocks,
)
from wheelcal.io.errors import InputError, TopicError
from wheelcal.io.imu_cdr import (
    CDR_MESSAGE_ENCODING,
    IMU_SCHEMA_NAME,
    ROS2_SCHEMA_ENCODING,
    ImuLayoutError,
    decode_imu_blocks,
)
from wheelcal.io.mcap_scan import ChannelRecord, McapScan, scan_mcap
from wheelcal.io.sample_checks import InputPolicy, clean_samples
from wheelcal.io.session_meta import SESSION_METADATA_NAME, session_info
from wheelcal.model.parameters import STANDARD_GRAVITY_MPS2
from wheelcal.recording import Recording

_IMU_NAMES = (IMU_SCHEMA_NAME, "sensor_msgs/Imu")
_EXPECTED = (
    f"{IMU_SCHEMA_NAME} ({ROS2_SCHEMA_ENCODING}/{CDR_MESSAGE_ENCODING}) or "
    f"{ACCEL_BATCH_SCHEMA_NAME} ({JSON_SCHEMA_ENCODING}/{JSON_MESSAGE_ENCODING})"
)


@dataclass(frozen=True)
class AccelTopic:
    """An accelerometer channel found in a file."""

    topic: str
    channel_id: int
    encoding: str  # "ros2" or "json"
    messages: int
    unit: str  # as the file states it


def _kind(scan: McapScan, channel: ChannelRecord) -> str | None:
    schema = scan.schema_of(channel)
    if schema is None:
        return None
    if (
        schema.encoding == ROS2_SCHEMA_ENCODING
        and schema.name in _IMU_NAMES
        and channel.message_encoding == CDR_MESSAGE_ENCODING
    ):
        return "ros2"
    if (
        schema.encoding == JSON_SCHEMA_ENCODING
        and schema.name == ACCEL_BATCH_SCHEMA_NAME
        and channel.message_encoding == JSON_MESSAGE_ENCODING
    ):
        return "json"
    return None


def accel_topics(scan: McapScan) -> list[AccelTopic]:
    """The channels whose schema is one of the contract's accelerometer formats."""
    out = []
    for channel in scan.channels.values():
        kind = _kind(scan, channel)
        if kind is None:
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
    """The accelerometer topics of an MCAP file (for a CLI listing)."""
    return accel_topics(scan_mcap(path))


def _decode(scan: McapScan, chosen: AccelTopic, where: str) -> tuple[np.ndarray, ...]:
    blocks = scan.blocks.get(chosen.channel_id, ())
    notes: list[str] = []
    try:
        if chosen.encoding == "ros2":
            stamp, log_time, accel = decode_imu_blocks(blocks)
            unstamped = stamp == 0
            if np.any(unstamped):
                stamp = np.where(unstamped, log_time, stamp)
                notes.append(
                    f"{int(unstamped.sum())} messages had a zero header.stamp; "
                    "their log time was used"
                )
            return stamp, accel, notes
        time_ns, accel = decode_accel_blocks(blocks)
        return time_ns, accel, notes
    except (ImuLayoutError, AccelBatchError) as exc:
        raise InputError(scan.path, f"{where}: {exc}") from None


def read_recording(
    path: str | os.PathLike,
    topic: str | None = None,
    info_overrides: Mapping[str, object] | None = None,
    *,
    info_defaults: Mapping[str, object] | None = None,
    accel_unit: str | None = None,
    policy: InputPolicy | None = None,
    gravity_checked: bool = True,
) -> Recording:
    """Read the accelerometer samples and session facts of an MCAP recording.

    Parameters
    ----------
    path:
        The MCAP file.
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
        (:class:`~wheelcal.io.sample_checks.InputPolicy`).
    gravity_checked:
        Refuse a ``gravity_mps2`` outside Earth's 9.7–9.9 m/s² (False: the
        user forced it).

    Returns
    -------
    Recording
        Times in s from the first sample (``epoch_unix_ns``), samples in m/s²,
        ``source`` = the path, ``topic``, and ``notes`` on anything repaired.
        ``info.radius_m`` may be ``None`` — see
        :func:`~wheelcal.io.session_meta.require_radius`.

    Raises
    ------
    InputError
        (and its subclasses ``NotMcapError``, ``CorruptFileError``,
        ``TopicError``, ``SessionInfoError``, ``SampleError``) with the file
        and the problem in the message.
    """
    policy = policy or InputPolicy()
    scan = scan_mcap(path)
    chosen = choose_topic(scan, topic)
    where = f"topic {chosen.topic}"
    records = [dict(values) for name, values in scan.metadata if name == SESSION_METADATA_NAME]
    info = session_info(
        scan.path, records, info_overrides, info_defaults, gravity_forced=not gravity_checked
    )

    unit = accel_unit or chosen.unit
    if unit not in UNITS:
        raise InputError(scan.path, f"{where}: unit {unit!r} is not one of {list(UNITS)}")
    time_ns, accel, notes = _decode(scan, chosen, where)
    if unit == "g":
        accel = accel * STANDARD_GRAVITY_MPS2  # CONTRACT: g always means 9.80665 m/s²
        notes.append("samples converted from g (9.80665 m/s²)")
    clean = clean_samples(
        f"{scan.path} ({where})",
        time_ns,
        accel,
        unit=unit,
        full_scale_g=info.full_scale_g,
        policy=policy,
    )
    if scan.chunks_without_crc:
        notes.append(
            f"{scan.chunks_without_crc} of {scan.chunks} chunks carry no CRC; "
            "their integrity could not be verified"
        )
    epoch = int(clean.time_ns[0])
    return Recording(
        time_s=(clean.time_ns - epoch) * 1e-9,
        accel_mps2=clean.accel_mps2,
        info=info,
        epoch_unix_ns=epoch,
        source=scan.path,
        topic=chosen.topic,
        notes=tuple(notes) + clean.notes,
        clip_limits_mps2=clean.clip_limits_mps2,
    )
