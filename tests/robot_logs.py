"""Robot logs written by the tools that write them, for the reader tests and the benchmark.

* rosbag2 ``.db3`` — ``rosbags.rosbag2.Writer`` (SQLite storage, metadata.yaml);
* ROS 1 ``.bag`` — ``rosbags.rosbag1.Writer`` (none, bz2 or lz4 chunks);
* ROS 1-encoded MCAP — the ``mcap`` library's ``Writer`` with the schema and
  channel ``mcap convert`` writes for a bag (``ros1msg`` / ``ros1``, the
  ``.msg`` text and md5sum from rosbags' ROS 1 type store).

Messages are serialised by rosbags' own serialisers from its ``sensor_msgs/Imu``
types (ROS 2 Humble and ROS 1 Noetic stores).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _stores():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE), get_typestore(Stores.ROS1_NOETIC)


def imu_messages(time_ns, accel_mps2, gyro_radps=None, ros1=False, frame_id="imu_link"):
    """Serialised ``sensor_msgs/Imu`` messages (CDR, or ROS 1 with ``ros1``)."""
    ros2_store, ros1_store = _stores()
    store = ros1_store if ros1 else ros2_store
    t = store.types
    imu, header = t["sensor_msgs/msg/Imu"], t["std_msgs/msg/Header"]
    stamp, vector, quaternion = (
        t["builtin_interfaces/msg/Time"],
        t["geometry_msgs/msg/Vector3"],
        t["geometry_msgs/msg/Quaternion"],
    )
    absent = np.zeros(9)
    absent[0] = -1.0
    zeros = np.zeros(9)
    out = []
    for i, (ns, a) in enumerate(
        zip(np.asarray(time_ns).tolist(), accel_mps2.tolist(), strict=True)
    ):
        sec, nsec = divmod(ns, 1_000_000_000)
        head = {"stamp": stamp(sec=sec, nanosec=nsec), "frame_id": frame_id}
        if ros1:
            head["seq"] = i
        w = gyro_radps[i] if gyro_radps is not None else (0.0, 0.0, 0.0)
        msg = imu(
            header=header(**head),
            orientation=quaternion(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=absent,
            angular_velocity=vector(x=float(w[0]), y=float(w[1]), z=float(w[2])),
            angular_velocity_covariance=zeros if gyro_radps is not None else absent,
            linear_acceleration=vector(x=a[0], y=a[1], z=a[2]),
            linear_acceleration_covariance=zeros,
        )
        name = "sensor_msgs/msg/Imu"
        raw = store.serialize_ros1(msg, name) if ros1 else store.serialize_cdr(msg, name)
        out.append(bytes(raw))
    return out


def write_db3(folder: Path, time_ns, messages, topic="/imu/data_raw", zstd_messages=False):
    """A rosbag2 folder (metadata.yaml + SQLite .db3) by rosbags; returns the .db3 file."""
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

    ros2_store, _ = _stores()
    writer = Writer(folder, version=8)
    if zstd_messages:
        writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with writer:
        connection = writer.add_connection(topic, "sensor_msgs/msg/Imu", typestore=ros2_store)
        for ns, raw in zip(np.asarray(time_ns).tolist(), messages, strict=True):
            writer.write(connection, ns, raw)
    (db3,) = folder.glob("*.db3")
    return db3


def write_bag(path: Path, time_ns, messages, topic="/imu/data_raw", compression="lz4"):
    """A ROS 1 bag by rosbags, chunks compressed ``none``, ``bz2`` or ``lz4``."""
    from rosbags.rosbag1 import Writer

    _, ros1_store = _stores()
    writer = Writer(path)
    if compression != "none":
        writer.set_compression(getattr(Writer.CompressionFormat, compression.upper()))
    with writer:
        connection = writer.add_connection(topic, "sensor_msgs/msg/Imu", typestore=ros1_store)
        for ns, raw in zip(np.asarray(time_ns).tolist(), messages, strict=True):
            writer.write(connection, ns, raw)
    return path


def write_ros1_mcap(path: Path, time_ns, messages, topic="/imu/data_raw"):
    """ROS 1 messages in an MCAP, with the schema and channel `mcap convert` gives a bag's."""
    from mcap.writer import Writer

    _, ros1_store = _stores()
    text, md5 = ros1_store.generate_msgdef("sensor_msgs/msg/Imu")
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start(profile="ros1", library="wheelcal tests (mcap Writer)")
        schema = writer.register_schema(
            name="sensor_msgs/Imu", encoding="ros1msg", data=text.encode("utf-8")
        )
        channel = writer.register_channel(
            topic=topic,
            message_encoding="ros1",
            schema_id=schema,
            metadata={"md5sum": md5, "callerid": "/imu_node", "latching": "0"},
        )
        for seq, (ns, raw) in enumerate(zip(np.asarray(time_ns).tolist(), messages, strict=True)):
            writer.add_message(channel, log_time=ns, data=raw, publish_time=ns, sequence=seq)
        writer.finish()
    return path
