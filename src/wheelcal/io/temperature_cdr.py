"""ROS 2 ``sensor_msgs/msg/Temperature`` in CDR: vectorised encode and decode.

The message is a ``std_msgs/Header`` and two float64s.  With ``L`` the length
field of ``header.frame_id`` (bytes including the NUL) and
``q = align8(12 + L)``, the body after the 4-byte encapsulation header is::

    offset  field
    0       header.stamp.sec            int32
    4       header.stamp.nanosec        uint32
    8       header.frame_id length L    uint32
    12      frame_id bytes + NUL        L bytes, then padding to a multiple of 8
    q       temperature                 float64 (degrees Celsius)
    q+8     variance                    float64 (0 = unknown)
    q+16    end

(the same alignment rules as :mod:`wheelcal.io.imu_cdr`, whose gather helper
this module shares).  Every message's size is checked against the layout.
"""

from __future__ import annotations

import numpy as np

from wheelcal.io.imu_cdr import _CDR_LE, ImuLayoutError, _gather, stamped_header
from wheelcal.io.mcap_scan import MessageBlock

TEMPERATURE_SCHEMA_NAME = "sensor_msgs/msg/Temperature"
_TAIL_BYTES = 16

#: The message definition as ``ros2 bag record`` stores it (dependencies appended).
TEMPERATURE_MSGDEF = """\
# Single temperature reading.

std_msgs/Header header # timestamp is the time the temperature was measured
                             # frame_id is the location of the temperature reading

float64 temperature # Measurement of the Temperature in Degrees Celsius.

float64 variance    # 0 is interpreted as variance unknown.

================================================================================
MSG: std_msgs/Header
# Standard metadata for higher-level stamped data types.

builtin_interfaces/Time stamp

string frame_id

================================================================================
MSG: builtin_interfaces/Time
# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

int32 sec
uint32 nanosec
"""


class TemperatureLayoutError(ImuLayoutError):
    """Message bytes that do not have the CDR layout of ``sensor_msgs/msg/Temperature``."""


def decode_temperature_blocks(blocks: tuple[MessageBlock, ...]) -> tuple[np.ndarray, ...]:
    """Stamps, log times and temperatures (°C) of CDR ``Temperature`` messages.

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
    first = 0  # the channel's index of the block's first message
    for block in blocks:
        first, before = first + block.count, first
        if block.count == 0:
            continue
        arr = np.frombuffer(block.buffer, dtype=np.uint8)
        off = block.payload_offsets
        if np.any(block.payload_lengths < 4 + 16 + _TAIL_BYTES):
            raise TemperatureLayoutError(
                "a message is too short to be a sensor_msgs/msg/Temperature"
            )
        kind = arr[off + 1]
        if np.any(arr[off] != 0) or np.any(kind > 1):
            raise TemperatureLayoutError("a Temperature message is not plain CDR")
        sec = np.empty(off.size, np.int64)
        nsec = np.empty(off.size, np.int64)
        temp = np.empty(off.size)
        for endian, code in (("<", 1), (">", 0)):
            sel = np.flatnonzero(kind == code)
            if sel.size == 0:
                continue
            header = stamped_header(arr, block, sel, endian, _TAIL_BYTES)
            sec[sel], nsec[sel] = header.sec, header.nsec
            if header.wrong_size is not None:
                at, actual, expected = header.wrong_size
                raise TemperatureLayoutError(
                    f"message {before + at}'s size does not match the "
                    f"sensor_msgs/msg/Temperature layout ({actual} bytes, expected {expected})"
                )
            temp[sel] = _gather(arr, header.body + header.q, endian + "f8")
        if np.any(nsec >= 1_000_000_000):
            raise TemperatureLayoutError("header.stamp.nanosec is 1e9 or more")
        stamps.append(sec * 1_000_000_000 + nsec)
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
    name = frame_id.encode("utf-8") + b"\x00"
    q = (12 + len(name) + 7) // 8 * 8
    dtype = np.dtype(
        {
            "names": ["encap", "sec", "nsec", "str_len", "frame", "temp", "var"],
            "formats": ["V4", "<i4", "<u4", "<u4", f"V{len(name)}", "<f8", "<f8"],
            "offsets": [0, 4, 8, 12, 16, 4 + q, 4 + q + 8],
            "itemsize": 4 + q + _TAIL_BYTES,
        }
    )
    rec = np.zeros(time_ns.size, dtype=dtype)
    rec["encap"] = np.void(_CDR_LE)
    sec, nsec = np.divmod(time_ns, 1_000_000_000)
    if np.any(sec > np.iinfo(np.int32).max) or np.any(sec < np.iinfo(np.int32).min):
        raise ValueError("stamps outside the int32 seconds range of builtin_interfaces/Time")
    rec["sec"] = sec
    rec["nsec"] = nsec
    rec["str_len"] = len(name)
    rec["frame"] = np.void(name)
    rec["temp"] = temp
    raw = rec.tobytes()
    size = dtype.itemsize
    return [raw[i : i + size] for i in range(0, len(raw), size)]
