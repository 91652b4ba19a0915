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


# --- a ROS 1 bag record by record (to damage what rosbags' writer always writes right) ---


def _bag_record(fields: dict, data: bytes) -> bytes:
    head = b"".join(
        len(k + b"=" + v).to_bytes(4, "little") + k + b"=" + v for k, v in fields.items()
    )
    return len(head).to_bytes(4, "little") + head + len(data).to_bytes(4, "little") + data


def _u32(v: int) -> bytes:
    return int(v).to_bytes(4, "little")


def _u64(v: int) -> bytes:
    return int(v).to_bytes(8, "little")


def raw_bag(
    time_ns,
    messages,
    *,
    compression: str = "none",
    chunk_data: bytes | None = None,
    chunk_size: int | None = None,
    drop: dict | None = None,
    values: dict | None = None,
    topic: str = "/imu/data_raw",
) -> bytes:
    """A ROS 1 bag 2.0 of one chunk, built record by record.

    ``compression`` names the chunk's compression (the data are compressed
    here, unless ``chunk_data`` gives them, with ``chunk_size`` as the claimed
    uncompressed size); ``drop`` removes header fields per record kind
    (``{"connection": "conn", "chunk": "size", "chunk info": "chunk_pos",
    "index data": "count"}``) and ``values`` replaces them (``{"connection":
    {"conn": b"\\x00\\x00"}}``) to make a damaged bag.
    """
    import bz2

    drop, values = drop or {}, values or {}

    def fields(kind: str, items: dict) -> dict:
        given = {k.encode(): v for k, v in values.get(kind, {}).items()}
        return {k: given.get(k, v) for k, v in items.items() if k.decode() != drop.get(kind)}

    _, ros1_store = _stores()
    text, md5 = ros1_store.generate_msgdef("sensor_msgs/msg/Imu")
    connection = _bag_record(
        fields("connection", {b"op": b"\x07", b"conn": _u32(0), b"topic": topic.encode()}),
        _bag_record(
            {
                b"topic": topic.encode(),
                b"type": b"sensor_msgs/Imu",
                b"md5sum": md5.encode(),
                b"message_definition": text.encode(),
            },
            b"",
        )[4:-4],
    )
    records, entries = [], []
    offset = 0
    for ns, raw in zip(np.asarray(time_ns).tolist(), messages, strict=True):
        sec, nsec = divmod(ns, 1_000_000_000)
        rec = _bag_record({b"op": b"\x02", b"conn": _u32(0), b"time": _u32(sec) + _u32(nsec)}, raw)
        entries.append(_u32(sec) + _u32(nsec) + _u32(offset))
        records.append(rec)
        offset += len(rec)
    inner = b"".join(records)
    if chunk_data is None:
        chunk_data = {"none": lambda b: b, "bz2": bz2.compress}[compression](inner)
        chunk_size = len(inner)
    chunk = _bag_record(
        fields(
            "chunk",
            {b"op": b"\x05", b"compression": compression.encode(), b"size": _u32(chunk_size)},
        ),
        chunk_data,
    )
    index = _bag_record(
        fields(
            "index data",
            {b"op": b"\x04", b"ver": _u32(1), b"conn": _u32(0), b"count": _u32(len(entries))},
        ),
        b"".join(entries),
    )
    magic = b"#ROSBAG V2.0\n"
    header_len = len(_bag_record({b"op": b"\x03", b"index_pos": _u64(0)}, b""))
    chunk_pos = len(magic) + header_len
    index_pos = chunk_pos + len(chunk) + len(index)
    first, last = int(time_ns[0]), int(time_ns[-1])
    chunk_info = _bag_record(
        fields(
            "chunk info",
            {
                b"op": b"\x06",
                b"ver": _u32(1),
                b"chunk_pos": _u64(chunk_pos),
                b"start_time": _u32(first // 10**9) + _u32(first % 10**9),
                b"end_time": _u32(last // 10**9) + _u32(last % 10**9),
                b"count": _u32(1),
            },
        ),
        _u32(0) + _u32(len(entries)),
    )
    header = _bag_record({b"op": b"\x03", b"index_pos": _u64(index_pos)}, b"")
    return magic + header + chunk + index + connection + chunk_info
