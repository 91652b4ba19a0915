"""ROS 2 ``sensor_msgs/msg/Imu`` in CDR: vectorised encode and decode.

A ROS 2 message in CDR is a 4-byte encapsulation header (``00 01 00 00`` for
little-endian CDR, ``00 00 ..`` for big-endian) followed by the fields, each
aligned to its own size *relative to the end of that header*.  For
``sensor_msgs/msg/Imu`` every field has a fixed size except the header's
``frame_id`` string, so with ``L`` = the string's length field (bytes
including its NUL terminator) and ``q = align8(12 + L)`` the body is::

    offset  field
    0       header.stamp.sec            int32
    4       header.stamp.nanosec        uint32
    8       header.frame_id length L    uint32
    12      frame_id bytes + NUL        L bytes, then padding to a multiple of 8
    q       orientation x, y, z, w      4 × float64
    q+32    orientation_covariance      9 × float64
    q+104   angular_velocity x, y, z    3 × float64
    q+128   angular_velocity_covariance 9 × float64
    q+200   linear_acceleration x, y, z 3 × float64
    q+224   linear_acceleration_covariance 9 × float64
    q+296   end

so a message is ``4 + q + 296`` bytes.  Decoding therefore needs one integer
per message (``L``) and a gather of 24 bytes — no per-message Python.  The
length is checked against this formula for every message, which also catches
a channel whose schema is not really ``sensor_msgs/msg/Imu``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.io.growing import GrowingColumns
from wheelcal.io.mcap_scan import MessageBlock

IMU_SCHEMA_NAME = "sensor_msgs/msg/Imu"
ROS2_SCHEMA_ENCODING = "ros2msg"
CDR_MESSAGE_ENCODING = "cdr"
_CDR_LE = b"\x00\x01\x00\x00"
_TAIL_BYTES = 296  # orientation … linear_acceleration_covariance
_ACCEL_AT = 200  # linear_acceleration, relative to q
_GYRO_AT = 104  # angular_velocity, relative to q
_GYRO_COV_AT = 128  # angular_velocity_covariance, relative to q

#: The message definition as ``ros2 bag record`` stores it (dependencies appended).
IMU_MSGDEF = """\
# This is a message to hold data from an IMU (Inertial Measurement Unit)
#
# Accelerations should be in m/s^2 (not in g's), and rotational velocity should be in rad/sec
#
# If the covariance of the measurement is known, it should be filled in (if all you know is the
# variance of each measurement, e.g. from the datasheet, just put those along the diagonal)
# A covariance matrix of all zeros will be interpreted as "covariance unknown", and to use the
# data a covariance will have to be assumed or gotten from some other source
#
# If you have no estimate for one of the data elements (e.g. your IMU doesn't produce an
# orientation estimate), please set element 0 of the associated covariance matrix to -1
# If you are interpreting this message, please check for a value of -1 in the first element of each
# covariance matrix, and disregard the associated estimate.

std_msgs/Header header

geometry_msgs/Quaternion orientation
float64[9] orientation_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance # Row major about x, y, z axes

geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance # Row major x, y, z

================================================================================
MSG: geometry_msgs/Quaternion
# This represents an orientation in free space in quaternion form.

float64 x 0
float64 y 0
float64 z 0
float64 w 1

================================================================================
MSG: geometry_msgs/Vector3
# This represents a vector in free space.

float64 x
float64 y
float64 z

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


class ImuLayoutError(ValueError):
    """Message bytes that do not have the CDR layout of ``sensor_msgs/msg/Imu``."""


def _gather(arr: np.ndarray, at: np.ndarray, dtype: str, count: int = 1) -> np.ndarray:
    """Values of ``dtype`` (count per message) starting at byte positions ``at``.

    Messages of one fixed-size type sit at a constant stride in a chunk; then a
    strided view reads them without building a byte index (the general case).
    """
    item = np.dtype(dtype).itemsize
    size = item * count
    if at.size > 1:
        step = int(at[1] - at[0])
        if step >= size and np.all(np.diff(at) == step):
            view = np.ndarray(
                (at.size, count), dtype=dtype, buffer=arr, offset=int(at[0]), strides=(step, item)
            )
            return view.reshape(-1) if count == 1 else view.copy()
    raw = arr[at[:, None] + np.arange(size)]
    out = raw.view(dtype)
    return out.reshape(-1) if count == 1 else out.reshape(-1, count)


def decode_imu_blocks(blocks: tuple[MessageBlock, ...]) -> tuple[np.ndarray, ...]:
    """Stamps, log times and linear accelerations of CDR ``Imu`` messages.

    Parameters
    ----------
    blocks:
        Message blocks of one channel, from :func:`~wheelcal.io.mcap_scan.scan_mcap`.

    Returns
    -------
    stamp_ns, log_time_ns : ndarray of int64, shape (N,)
        ``header.stamp`` as nanoseconds, and the MCAP log time.
    accel : ndarray, shape (N, 3)
        ``linear_acceleration`` (m/s² per REP 103).

    Raises
    ------
    ImuLayoutError
        A message whose size or encapsulation does not fit the Imu layout.
    """
    return _decode(blocks, gyro=False)[:3]


def decode_imu_with_gyro(
    blocks: tuple[MessageBlock, ...], decode_block=None
) -> tuple[np.ndarray, ...]:
    """As :func:`decode_imu_blocks`, plus ``angular_velocity``.

    ``decode_block`` decodes one block (default: CDR; ROS 1:
    :func:`wheelcal.io.imu_ros1.decode_ros1_block`).

    Returns
    -------
    stamp_ns, log_time_ns, accel
        As :func:`decode_imu_blocks`.
    gyro : ndarray, shape (N, 3), or None
        ``angular_velocity`` in rad/s (REP 103); a row of NaN where the
        message marks it absent (``angular_velocity_covariance[0] == -1``);
        ``None`` when every message does.  (A channel of exact zeros is the
        caller's to judge: it is absent too, by convention of many drivers.)
    """
    return _decode(blocks, gyro=True, decode_block=decode_block)


@dataclass(frozen=True)
class StampedHeader:
    """The ``std_msgs/Header`` of one block's messages of one byte order."""

    sec: np.ndarray
    nsec: np.ndarray
    body: np.ndarray  # byte offset of each message's body (after the 4-byte encapsulation)
    q: np.ndarray  # the header's size, padded to 8 (the first field after it starts there)
    #: (block index, its size, the size its layout needs) of the first message of the
    #: wrong size, or None.
    wrong_size: tuple[int, int, int] | None


def stamped_header(
    arr: np.ndarray, block: MessageBlock, sel: np.ndarray, endian: str, tail_bytes: int
) -> StampedHeader:
    """Stamps and layout of the messages ``sel`` of ``block`` (one byte order).

    A stamped message is the header (stamp, frame_id string) and ``tail_bytes``
    of fixed fields after it, 8-aligned; CDR allows up to 3 bytes of final
    padding (XCDR options field).
    """
    body = block.payload_offsets[sel] + 4
    sec = _gather(arr, body, endian + "i4")
    nsec = _gather(arr, body + 4, endian + "u4")
    str_len = _gather(arr, body + 8, endian + "u4").astype(np.int64)
    q = (12 + str_len + 7) // 8 * 8
    expected = 4 + q + tail_bytes
    actual = block.payload_lengths[sel]
    wrong = (actual < expected) | (actual > expected + 3)
    wrong_size = None
    if np.any(wrong):
        at = int(np.argmax(wrong))
        wrong_size = (int(sel[at]), int(actual[at]), int(expected[at]))
    return StampedHeader(sec, nsec, body, q, wrong_size)


def _decode_block(block: MessageBlock, gyro: bool, first_message: int = 0) -> tuple:
    """Stamps, log times, accelerations and (None or) gyro rows of one block.

    ``first_message`` is the channel's index of the block's first message
    (for error messages).
    """
    arr = np.frombuffer(block.buffer, dtype=np.uint8)
    off = block.payload_offsets
    short = block.payload_lengths < 4 + 12 + _TAIL_BYTES
    if np.any(short):
        at = int(np.argmax(short))
        raise ImuLayoutError(
            f"message {first_message + at} is too short to be a sensor_msgs/msg/Imu "
            f"({int(block.payload_lengths[at])} bytes)"
        )
    kind = arr[off + 1]
    bad = (arr[off] != 0) | (kind > 1)
    if np.any(bad):
        raise ImuLayoutError(
            f"message {first_message + int(np.argmax(bad))} is not plain CDR "
            "(encapsulation kind is not CDR_LE/BE)"
        )
    sec = np.empty(off.size, np.int64)
    nsec = np.empty(off.size, np.int64)
    accel = np.empty((off.size, 3))
    rate = None
    for endian, code in (("<", 1), (">", 0)):
        sel = np.flatnonzero(kind == code)
        if sel.size == 0:
            continue
        header = stamped_header(arr, block, sel, endian, _TAIL_BYTES)
        sec[sel], nsec[sel], body, q = header.sec, header.nsec, header.body, header.q
        if header.wrong_size is not None:
            at, actual, expected = header.wrong_size
            raise ImuLayoutError(
                f"message {first_message + at}'s size does not match the "
                f"sensor_msgs/msg/Imu layout ({actual} bytes, expected {expected})"
            )
        tail = body + q
        accel[sel] = _gather(arr, tail + _ACCEL_AT, endian + "f8", 3)
        if gyro:
            rate = imu_gyro_rows(arr, tail, endian, sel, off.size, rate)
    late = nsec >= 1_000_000_000
    if np.any(late):
        raise ImuLayoutError(
            f"message {first_message + int(np.argmax(late))}: header.stamp.nanosec is 1e9 or more"
        )
    return sec * 1_000_000_000 + nsec, block.log_time_ns, accel, rate


def imu_gyro_rows(
    arr: np.ndarray,
    tail: np.ndarray,
    endian: str,
    sel: np.ndarray,
    size: int,
    rate: np.ndarray | None,
) -> np.ndarray | None:
    """``angular_velocity`` of messages ``sel`` into ``rate`` (NaN rows where absent).

    ``tail`` is each message's byte position of ``orientation`` (the 296
    fixed bytes after the header, the same in CDR and ROS 1); ``rate`` is
    created (size × 3, NaN) at the first message that has a gyro reading.
    Covariance element 0 == −1 means "no estimate" (the message definition).
    """
    present = _gather(arr, tail + _GYRO_COV_AT, endian + "f8") != -1.0
    if np.any(present):
        if rate is None:
            rate = np.full((size, 3), np.nan)
        rate[sel[present]] = _gather(arr, tail[present] + _GYRO_AT, endian + "f8", 3)
    return rate


def _decode(blocks: tuple[MessageBlock, ...], gyro: bool, decode_block=None) -> tuple:
    stamps, logs, accels, gyros = [], [], [], []
    any_gyro = False
    first = 0
    decode_block = decode_block or _decode_block
    for block in blocks:
        if block.count == 0:
            continue
        stamp, log, accel, rate = decode_block(block, gyro, first)
        first += block.count
        stamps.append(stamp)
        logs.append(log)
        accels.append(accel)
        any_gyro |= rate is not None
        gyros.append(rate if rate is not None else np.full((stamp.size, 3), np.nan))
    if not stamps:
        empty = (np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, 3)))
        return (*empty, None)
    rate_all = np.concatenate(gyros) if any_gyro and gyro else None
    return np.concatenate(stamps), np.concatenate(logs), np.concatenate(accels), rate_all


class ImuSink:
    """Decodes an Imu channel block by block as the scan finds it (see ``scan_mcap``).

    Keeps per sample the time (``header.stamp``, or the log time where the
    stamp is zero), the acceleration and, when any message has one, the gyro:
    24–56 B instead of the message's ~340.  A decoding error is kept and
    raised by :meth:`result`.
    """

    def __init__(self, decode_block=None) -> None:
        self.count = 0
        self.unstamped = 0
        self._columns = GrowingColumns()
        self._error: ImuLayoutError | None = None
        #: ``(block, gyro, first_message) -> (stamp, log, accel, rate)``: CDR by default,
        #: :func:`wheelcal.io.imu_ros1.decode_ros1_block` for ROS 1 messages.
        self._decode_block = decode_block or _decode_block

    def add(self, block: MessageBlock) -> None:
        """Decode one block's messages into the columns."""
        first = self.count
        self.count += block.count
        if self._error is not None or block.count == 0:
            return
        try:
            stamp, log, accel, rate = self._decode_block(block, True, first)
        except ImuLayoutError as exc:
            self._error = exc
            return
        zero = stamp == 0
        if np.any(zero):
            self.unstamped += int(zero.sum())
            stamp = np.where(zero, log, stamp)
        self._columns.append(time_ns=stamp, accel=accel, gyro=rate)

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(time_ns, accel, gyro or None) of every message; raises the first decoding error."""
        if self._error is not None:
            raise self._error
        columns = self._columns.finish()
        if not columns:
            return np.empty(0, np.int64), np.empty((0, 3)), None
        return columns["time_ns"], columns["accel"], columns.get("gyro")


def encode_imu_messages(
    time_ns: np.ndarray,
    accel_mps2: np.ndarray,
    frame_id: str,
    gyro_radps: np.ndarray | None = None,
    accel_covariance_mps2sq: np.ndarray | None = None,
) -> list[bytes]:
    """CDR little-endian ``Imu`` payloads with ``linear_acceleration`` (and the gyro) filled.

    Orientation is marked "not provided" by setting element 0 of its
    covariance to −1 (the convention the message definition documents); so is
    ``angular_velocity`` when ``gyro_radps`` is ``None``, or on the rows of
    ``gyro_radps`` that are NaN (left out).  ``linear_acceleration_covariance``
    is ``accel_covariance_mps2sq`` (3 × 3, (m/s²)², row-major in the message)
    when given; other covariances are all zero ("unknown").

    Parameters
    ----------
    time_ns:
        Stamps, integer nanoseconds since the Unix epoch, shape (N,).
    accel_mps2:
        Linear acceleration, shape (N, 3).
    frame_id:
        ``header.frame_id`` for every message.
    gyro_radps:
        Angular velocity (N, 3) in rad/s, or ``None``.
    accel_covariance_mps2sq:
        The samples' noise covariance (3, 3), or ``None`` (zeros: unknown).

    Returns
    -------
    list of bytes
        One payload per sample.
    """
    time_ns = np.asarray(time_ns, dtype=np.int64)
    accel = np.asarray(accel_mps2, dtype=float).reshape(-1, 3)
    name = frame_id.encode("utf-8") + b"\x00"
    q = (12 + len(name) + 7) // 8 * 8
    tail = [4 + q + k for k in (0, 32, _GYRO_AT, _GYRO_COV_AT, _ACCEL_AT, 224)]
    names = ["encap", "sec", "nsec", "str_len", "frame", "orient", "orient_cov"]
    names += ["gyro", "gyro_cov", "accel", "accel_cov"]
    formats = ["V4", "<i4", "<u4", "<u4", f"V{len(name)}", ("<f8", 4), ("<f8", 9)]
    formats += [("<f8", 3), ("<f8", 9), ("<f8", 3), ("<f8", 9)]
    dtype = np.dtype(
        {
            "names": names,
            "formats": formats,
            "offsets": [0, 4, 8, 12, 16, *tail],
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
    rec["orient"][:, 3] = 1.0  # identity quaternion (ignored: covariance[0] = -1)
    rec["orient_cov"][:, 0] = -1.0
    if gyro_radps is None:
        rec["gyro_cov"][:, 0] = -1.0
    else:
        rate = np.asarray(gyro_radps, dtype=float).reshape(-1, 3)
        if rate.shape[0] != time_ns.size:
            raise ValueError(f"{time_ns.size} stamps but {rate.shape[0]} gyro rows")
        absent = ~np.all(np.isfinite(rate), axis=1)
        rec["gyro"] = np.where(absent[:, None], 0.0, rate)
        rec["gyro_cov"][absent, 0] = -1.0
    rec["accel"] = accel
    if accel_covariance_mps2sq is not None:
        cov = np.asarray(accel_covariance_mps2sq, dtype=float).reshape(3, 3)
        if not np.all(np.isfinite(cov)):
            raise ValueError("the acceleration covariance must be finite")
        rec["accel_cov"] = cov.reshape(-1)
    raw = rec.tobytes()
    size = dtype.itemsize
    return [raw[i : i + size] for i in range(0, len(raw), size)]
