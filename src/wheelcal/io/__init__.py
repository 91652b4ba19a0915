"""File input and output: MCAP recordings (contract formats), CSV conversion, atomic writes.

Read a device recording with :func:`read_recording` (accelerometer, and the
gyro and temperature when the file has them); write one with
:func:`write_recording`; add a channel to a copy with :func:`copy_with_channels`.
Errors are :class:`InputError` subclasses whose message names the file and
the problem.
"""

from wheelcal.io.atomic import atomic_output, atomic_write_bytes, atomic_write_text
from wheelcal.io.csv_convert import CsvConversion, CsvLayout, convert_csv
from wheelcal.io.errors import (
    CorruptFileError,
    InputError,
    NotMcapError,
    SampleError,
    SessionInfoError,
    TopicError,
)
from wheelcal.io.mcap_reader import (
    AccelTopic,
    RawImuSamples,
    choose_topic,
    list_accel_topics,
    read_raw_samples,
    read_recording,
)
from wheelcal.io.mcap_writer import (
    ChannelData,
    accel_channel,
    copy_with_channels,
    session_metadata,
    temperature_channel,
    write_accel_mcap,
    write_recording,
)
from wheelcal.io.session_meta import require_radius
from wheelcal.recording.samples import InputPolicy

__all__ = [
    "AccelTopic",
    "ChannelData",
    "CorruptFileError",
    "CsvConversion",
    "CsvLayout",
    "InputError",
    "InputPolicy",
    "NotMcapError",
    "RawImuSamples",
    "SampleError",
    "SessionInfoError",
    "TopicError",
    "accel_channel",
    "atomic_output",
    "atomic_write_bytes",
    "atomic_write_text",
    "choose_topic",
    "convert_csv",
    "copy_with_channels",
    "list_accel_topics",
    "read_raw_samples",
    "read_recording",
    "require_radius",
    "session_metadata",
    "temperature_channel",
    "write_accel_mcap",
    "write_recording",
]
