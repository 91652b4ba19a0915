"""ROS 1 ``sensor_msgs/Imu``: vectorised decode of its serialisation.

ROS 1 serialises little-endian, with no alignment and no encapsulation
header.  ``std_msgs/Header`` is ``uint32 seq``, ``time stamp`` (``uint32
sec``, ``uint32 nsec``) and ``string frame_id`` (``uint32`` length, then the
bytes, no terminator); the 296 fixed bytes that follow are the same fields as
in CDR (:mod:`wheelcal.io.imu_cdr`), in the same order and offsets::

    offset     field
    0          header.seq                 uint32
    4          header.stamp.sec           uint32
    8          header.stamp.nsec          uint32
    12         header.frame_id length L   uint32
    16         frame_id bytes             L bytes
    16+L       orientation … linear_acceleration_covariance (as in CDR, 296 bytes)

so a message is ``16 + L + 296`` bytes, checked for every message.  This is
what a ROS 1 ``.bag`` holds and what ``mcap convert`` writes into an MCAP
with message encoding ``ros1`` (schema encoding ``ros1msg``).
"""

from __future__ import annotations

import numpy as np

from wheelcal.io.channel_format import ChannelFormat
from wheelcal.io.imu_cdr import _ACCEL_AT, _TAIL_BYTES, ImuLayoutError, imu_gyro_rows
from wheelcal.io.mcap_scan import MessageBlock
from wheelcal.io.ros2_cdr import gather

ROS1_IMU_SCHEMA_NAME = "sensor_msgs/Imu"
ROS1_SCHEMA_ENCODING = "ros1msg"
ROS1_MESSAGE_ENCODING = "ros1"
ROS1_IMU_FORMAT = ChannelFormat(
    ROS1_IMU_SCHEMA_NAME,
    ROS1_SCHEMA_ENCODING,
    ROS1_MESSAGE_ENCODING,
    also_named=("sensor_msgs/msg/Imu",),  # a ROS 2 type name kept by a converter
)
_HEADER_FIXED = 16  # seq, sec, nsec, frame_id length


def decode_ros1_block(block: MessageBlock, gyro: bool, first_message: int = 0) -> tuple:
    """Stamps (ns), log times, accelerations and (None or) gyro rows of ROS 1 Imu messages.

    ``first_message`` is the channel's index of the block's first message (for
    error messages).

    Raises
    ------
    ImuLayoutError
        A message whose size does not fit the ROS 1 ``sensor_msgs/Imu`` layout.
    """
    arr = np.frombuffer(block.buffer, dtype=np.uint8)
    body = block.payload_offsets
    length = block.payload_lengths
    short = length < _HEADER_FIXED + _TAIL_BYTES
    if np.any(short):
        at = int(np.argmax(short))
        raise ImuLayoutError(
            f"message {first_message + at} is too short to be a ROS 1 sensor_msgs/Imu "
            f"({int(length[at])} bytes)"
        )
    sec = gather(arr, body + 4, "<u4").astype(np.int64)
    nsec = gather(arr, body + 8, "<u4").astype(np.int64)
    name_len = gather(arr, body + 12, "<u4").astype(np.int64)
    expected = _HEADER_FIXED + name_len + _TAIL_BYTES
    wrong = length != expected
    if np.any(wrong):
        at = int(np.argmax(wrong))
        raise ImuLayoutError(
            f"message {first_message + at}'s size does not match the ROS 1 sensor_msgs/Imu "
            f"layout ({int(length[at])} bytes, expected {int(expected[at])})"
        )
    late = nsec >= 1_000_000_000
    if np.any(late):
        raise ImuLayoutError(
            f"message {first_message + int(np.argmax(late))}: header.stamp.nsec is 1e9 or more"
        )
    tail = body + _HEADER_FIXED + name_len
    accel = gather(arr, tail + _ACCEL_AT, "<f8", 3)
    rate = None
    if gyro:
        rate = imu_gyro_rows(arr, tail, "<", np.arange(body.size), body.size, None)
    return sec * 1_000_000_000 + nsec, block.log_time_ns, accel, rate
