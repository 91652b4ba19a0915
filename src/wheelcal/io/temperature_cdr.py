"""ROS 2 ``sensor_msgs/msg/Temperature`` in CDR: vectorised encode and decode.

The message is a ``std_msgs/Header`` and two float64s (the stamped layout of
:mod:`wheelcal.io.ros2_cdr`); with ``q`` the header's size padded to 8, the
body after the 4-byte encapsulation header is::

    offset  field
    0       header (stamp, frame_id)    q bytes
    q       temperature                 float64 (degrees Celsius)
    q+8     variance                    float64 (0 = unknown)
    q+16    end

Every message's size is checked against the layout.
"""

from __future__ import annotations

import numpy as np

from wheelcal.io import ros2_cdr as cdr
from wheelcal.io.channel_format import ChannelFormat
from wheelcal.io.imu_cdr import ImuLayoutError
from wheelcal.io.mcap_scan import MessageBlock

TEMPERATURE_SCHEMA_NAME = "sensor_msgs/msg/Temperature"
_TAIL_BYTES = 16

#: The message definition as ``ros2 bag record`` stores it (dependencies appended).
TEMPERATURE_MSGDEF = cdr.message_definition(
    """\
# Single temperature reading.

std_msgs/Header header # timestamp is the time the temperature was measured
                             # frame_id is the location of the temperature reading

float64 temperature # Measurement of the Temperature in Degrees Celsius.

float64 variance    # 0 is interpreted as variance unknown.
""",
    "std_msgs/Header",
    "builtin_interfaces/Time",
)
TEMPERATURE_FORMAT = ChannelFormat(
    TEMPERATURE_SCHEMA_NAME,
    cdr.ROS2_SCHEMA_ENCODING,
    cdr.CDR_MESSAGE_ENCODING,
    TEMPERATURE_MSGDEF.encode("utf-8"),
    also_named=("sensor_msgs/Temperature",),
)


class TemperatureLayoutError(ImuLayoutError):
    """Message bytes that do not have the CDR layout of ``sensor_msgs/msg/Temperature``."""


def decode_temperature_blocks(
    blocks: tuple[MessageBlock, ...], first_message: int = 0
) -> tuple[np.ndarray, ...]:
    """Stamps, log times and temperatures (°C) of CDR ``Temperature`` messages.

    ``first_message`` is the channel's index of the first message (for errors).

    Returns
    -------
    stamp_ns, log_time_ns : ndarray of int64, shape (N,)
    temperature_c : ndarray, shape (N,)

    Raises
    ------
    TemperatureLayoutError
        A message whose size or encapsulation does not fit the layout.
    """
    stamps, logs, temps = [], [], []
    first = first_message  # the channel's index of the block's first message
    for block in blocks:
        first, before = first + block.count, first
        if block.count == 0:
            continue
        messages = cdr.stamped_messages(
            block, TEMPERATURE_SCHEMA_NAME, _TAIL_BYTES, before, TemperatureLayoutError
        )
        temp = np.empty(block.payload_offsets.size)
        for endian, sel, tail in messages.parts:
            temp[sel] = cdr.gather(messages.arr, tail, endian + "f8")
        stamps.append(messages.stamp_ns)
        logs.append(block.log_time_ns)
        temps.append(temp)
    if not stamps:
        return np.empty(0, np.int64), np.empty(0, np.int64), np.empty(0)
    return np.concatenate(stamps), np.concatenate(logs), np.concatenate(temps)


def encode_temperature_messages(
    time_ns: np.ndarray, temperature_c: np.ndarray, frame_id: str
) -> list[bytes]:
    """CDR little-endian ``Temperature`` payloads (variance 0 = unknown), one per stamp."""
    time_ns = np.asarray(time_ns, dtype=np.int64).reshape(-1)
    temp = np.asarray(temperature_c, dtype=float).reshape(-1)
    if temp.size != time_ns.size:
        raise ValueError(f"{time_ns.size} stamps but {temp.size} temperatures")
    fields = [("temp", "<f8", 0), ("var", "<f8", 8)]  # variance 0: unknown
    rec = cdr.stamped_records(time_ns, frame_id, fields, _TAIL_BYTES)
    rec["temp"] = temp
    return cdr.payloads(rec)
