"""File input and output: MCAP recordings (contract formats), CSV conversion, atomic writes.

Layer 3 (above ``recording``, beside ``simulate`` and ``estimate``, below ``closedloop``).

Read a device recording with :func:`read_recording` (accelerometer, and the
gyro and temperature when the file has them); write one with
:func:`write_recording`; add a channel to a copy with :func:`copy_with_channels`.
Errors are :class:`InputError` subclasses whose message names the file and
the problem.

The front also holds what the writers above use: atomic writes and staged output
folders (:mod:`.atomic`), the marks that claim a file as wheelcal's before it is
overwritten (:mod:`.ownership`), bounded reads of small input files
(:mod:`.input_file`, :mod:`.file_kind`), the JSON text of the documents
(:mod:`.json_text`), an error in words (:func:`describe_error`) and whether a failed
write means a full disk (:mod:`.full_disk`).
"""

from wheelcal.io.atomic import (
    OutputExistsError,
    OutputFolderError,
    atomic_output,
    atomic_path,
    atomic_write_bytes,
    atomic_write_text,
    prepare_output_folder,
    refuse_existing,
    remove_temporaries,
    staged_outputs,
)
from wheelcal.io.csv_convert import CsvConversion, CsvLayout, convert_csv
from wheelcal.io.errors import (
    CorruptFileError,
    InputError,
    MetadataError,
    NotMcapError,
    SampleError,
    TopicError,
    describe_error,
)
from wheelcal.io.file_kind import special_file_kind
from wheelcal.io.full_disk import disk_full
from wheelcal.io.input_file import SpecialFileError, read_bounded
from wheelcal.io.json_text import dumps_indented, json_safe
from wheelcal.io.mcap_reader import (
    AccelTopic,
    RawImuSamples,
    choose_topic,
    list_accel_topics,
    read_raw_samples,
    read_recording,
)
from wheelcal.io.mcap_scan import is_mcap_file
from wheelcal.io.mcap_writer import (
    ChannelData,
    accel_channel,
    copy_with_channels,
    recording_stamps_ns,
    session_metadata,
    temperature_channel,
    write_accel_mcap,
    write_channels,
    write_recording,
)
from wheelcal.io.ownership import (
    MARK_KEY,
    MARK_RECORD,
    MARK_TEXT,
    Output,
    OutputRefusedError,
    claim_outputs,
    mark_line,
    origin_of,
    output_mark,
)
from wheelcal.io.sample_flags import flags_channel
from wheelcal.io.session_meta import require_radius
from wheelcal.recording import InputPolicy

__all__ = [
    "MARK_KEY",
    "MARK_RECORD",
    "MARK_TEXT",
    "AccelTopic",
    "ChannelData",
    "CorruptFileError",
    "CsvConversion",
    "CsvLayout",
    "InputError",
    "InputPolicy",
    "MetadataError",
    "NotMcapError",
    "Output",
    "OutputExistsError",
    "OutputFolderError",
    "OutputRefusedError",
    "RawImuSamples",
    "SampleError",
    "SpecialFileError",
    "TopicError",
    "accel_channel",
    "atomic_output",
    "atomic_path",
    "atomic_write_bytes",
    "atomic_write_text",
    "choose_topic",
    "claim_outputs",
    "convert_csv",
    "copy_with_channels",
    "describe_error",
    "disk_full",
    "dumps_indented",
    "flags_channel",
    "is_mcap_file",
    "json_safe",
    "list_accel_topics",
    "mark_line",
    "origin_of",
    "output_mark",
    "prepare_output_folder",
    "read_bounded",
    "read_raw_samples",
    "read_recording",
    "recording_stamps_ns",
    "refuse_existing",
    "remove_temporaries",
    "require_radius",
    "session_metadata",
    "special_file_kind",
    "staged_outputs",
    "temperature_channel",
    "write_accel_mcap",
    "write_channels",
    "write_recording",
]
