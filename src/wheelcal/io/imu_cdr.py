"""ROS 2 ``sensor_msgs/msg/Imu`` in CDR: vectorised encode and decode.

Every field of ``sensor_msgs/msg/Imu`` has a fixed size except its header's
``frame_id`` string (the stamped layout of :mod:`wheelcal.io.ros2_cdr`), so
with ``q`` the header's size padded to 8 the body after the 4-byte
encapsulation is::

    offset  field
    0       header (stamp, frame_id)    q bytes
    q       orientation x, y, z, w      4 × float64
    q+32    orientation_covariance      9 × float64
    q+104   angular_velocity x, y, z    3 × float64
    q+128   angular_velocity_covariance 9 × float64
    q+200   linear_acceleration x, y, z 3 × float64
    q+224   linear_acceleration_covariance 9 × float64
    q+296   end

so a message is ``4 + q + 296`` bytes.  Decoding therefore needs one integer
per message (the string's length) and a gather of 24 bytes — no per-message
Python.  The length is checked against this formula for every message, which
also catches a channel whose schema is not really ``sensor_msgs/msg/Imu``.
"""

from __future__ import annotations

import numpy as np

from wheelcal.io.channel_format import ChannelFormat
from wheelcal.io.growing import ColumnSink
from wheelcal.io.mcap_scan import MessageBlock
from wheelcal.io.ros2_cdr import (
    CDR_MESSAGE_ENCODING,
    ROS2_SCHEMA_ENCODING,
    gather,
    message_definition,
    payloads,
    stamped_messages,
    stamped_records,
)

IMU_SCHEMA_NAME = "sensor_msgs/msg/Imu"
_TAIL_BYTES = 296  # orientation … linear_acceleration_covariance
_ACCEL_AT = 200  # linear_acceleration, relative to q
_GYRO_AT = 104  # angular_velocity, relative to q
_GYRO_COV_AT = 128  # angular_velocity_covariance, relative to q

#: The message definition as ``ros2 bag record`` stores it (dependencies appended).
IMU_MSGDEF = message_definition(
    """\
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
""",
    "geometry_msgs/Quaternion",
    "geometry_msgs/Vector3",
    "std_msgs/Header",
    "builtin_interfaces/Time",
)
IMU_FORMAT = ChannelFormat(
    IMU_SCHEMA_NAME,
    ROS2_SCHEMA_ENCODING,
    CDR_MESSAGE_ENCODING,
    IMU_MSGDEF.encode("utf-8"),
    also_named=("sensor_msgs/Imu",),  # a ROS 1 type name kept by a converter
)


class ImuLayoutError(ValueError):
    """Message bytes that do not have the CDR layout of ``sensor_msgs/msg/Imu``."""


def decode_imu_with_gyro(
    blocks: tuple[MessageBlock, ...], decode_block=None
) -> tuple[np.ndarray, ...]:
    """Stamps, log times, linear accelerations and angular velocities of ``Imu`` messages.

    ``blocks`` are one channel's, from :func:`~wheelcal.io.mcap_scan.scan_mcap`;
    ``decode_block`` decodes one block (default: CDR; ROS 1:
    :func:`wheelcal.io.imu_ros1.decode_ros1_block`).

    Returns
    -------
    stamp_ns, log_time_ns : ndarray of int64, shape (N,)
        ``header.stamp`` as nanoseconds, and the MCAP log time.
    accel : ndarray, shape (N, 3)
        ``linear_acceleration`` (m/s² per REP 103).
    gyro : ndarray, shape (N, 3), or None
        ``angular_velocity`` in rad/s (REP 103); a row of NaN where the
        message marks it absent (``angular_velocity_covariance[0] == -1``);
        ``None`` when every message does.  (A channel of exact zeros is the
        caller's to judge: it is absent too, by convention of many drivers.)
    """
    return _decode(blocks, gyro=True, decode_block=decode_block)


def _decode_block(block: MessageBlock, gyro: bool, first_message: int = 0) -> tuple:
    """Stamps, log times, accelerations and (None or) gyro rows of one block.

    ``first_message`` is the channel's index of the block's first message
    (for error messages).
    """
    messages = stamped_messages(block, IMU_SCHEMA_NAME, _TAIL_BYTES, first_message, ImuLayoutError)
    size = block.payload_offsets.size
    accel = np.empty((size, 3))
    rate = None
    for endian, sel, tail in messages.parts:
        accel[sel] = gather(messages.arr, tail + _ACCEL_AT, endian + "f8", 3)
        if gyro:
            rate = imu_gyro_rows(messages.arr, tail, endian, sel, size, rate)
    return messages.stamp_ns, block.log_time_ns, accel, rate


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
    present = gather(arr, tail + _GYRO_COV_AT, endian + "f8") != -1.0
    if np.any(present):
        if rate is None:
            rate = np.full((size, 3), np.nan)
        rate[sel[present]] = gather(arr, tail[present] + _GYRO_AT, endian + "f8", 3)
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


class ImuSink(ColumnSink):
    """Decodes an Imu channel block by block as the scan finds it (see ``scan_mcap``).

    Keeps per sample the time (``header.stamp``, or the log time where the
    stamp is zero), the acceleration and, when any message has one, the gyro:
    24–56 B instead of the message's ~340.  A decoding error is kept and
    raised by :meth:`result`.
    """

    errors = (ImuLayoutError,)

    def __init__(self, decode_block=None) -> None:
        super().__init__()
        self.unstamped = 0
        #: ``(block, gyro, first_message) -> (stamp, log, accel, rate)``: CDR by default,
        #: :func:`wheelcal.io.imu_ros1.decode_ros1_block` for ROS 1 messages.
        self._decode_block = decode_block or _decode_block

    def decode(self, block: MessageBlock, first_message: int) -> dict[str, np.ndarray | None]:
        """One block's times (log time where the stamp is zero), accelerations and gyro rows."""
        stamp, log, accel, rate = self._decode_block(block, True, first_message)
        zero = stamp == 0
        if np.any(zero):
            self.unstamped += int(zero.sum())
            stamp = np.where(zero, log, stamp)
        return {"time_ns": stamp, "accel": accel, "gyro": rate}

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """(time_ns, accel, gyro or None) of every message; raises the first decoding error."""
        columns = self.columns()
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
    fields = [
        ("orient", ("<f8", 4), 0),
        ("orient_cov", ("<f8", 9), 32),
        ("gyro", ("<f8", 3), _GYRO_AT),
        ("gyro_cov", ("<f8", 9), _GYRO_COV_AT),
        ("accel", ("<f8", 3), _ACCEL_AT),
        ("accel_cov", ("<f8", 9), 224),
    ]
    rec = stamped_records(time_ns, frame_id, fields, _TAIL_BYTES)
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
    return payloads(rec)
