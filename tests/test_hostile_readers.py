"""Issue 40, items 1 and 3: the ROS 1 and rosbag2 readers held to the MCAP reader's standard.

* Every decompressor is bounded (:mod:`wheelcal.io.bounded_decompress`): the
  bombs below are read in a subprocess whose data segment is limited to
  1.5 GiB, so a regression fails the test (MemoryError) instead of exhausting
  the machine.  Before issue 40 each of them ran out of memory.
* Every malformed field is named: the file, the record and what is wrong
  (before: ``KeyError: 'conn'``, ``TypeError: int() argument must be …``, a
  ``UnicodeDecodeError`` without the file, "50 % repeated stamps", "not an
  MCAP file").
"""

import sqlite3

import numpy as np
import pytest

from bombs import MIB, bz2_zeros, lz4_zeros, mcap_record, mcap_string, read_limited, zstd_zeros
from robot_logs import imu_messages, raw_bag, write_db3
from wheelcal.cli.main import main
from wheelcal.io import CorruptFileError, NotMcapError, read_recording
from wheelcal.io.mcap_scan import MAGIC


@pytest.fixture(scope="module")
def short():
    """2,400 samples (12 s at 200 Hz)."""
    rng = np.random.default_rng(4)
    time_ns = 1_700_000_000_000_000_000 + np.arange(2400) * 5_000_000
    accel = rng.normal([0.1, -0.2, 9.8], 0.05, size=(2400, 3))
    return time_ns, accel


# --- item 1: bombs ------------------------------------------------------------------------


def test_a_bz2_bag_chunk_claiming_gigabytes_is_refused_before_decompressing(tmp_path, short):
    time_ns, accel = short
    messages = imu_messages(time_ns, accel, ros1=True)
    data = bz2_zeros(3000)  # 3000 MiB of zeros in ~120 KB
    path = tmp_path / "bomb.bag"
    path.write_bytes(
        raw_bag(time_ns, messages, compression="bz2", chunk_data=data, chunk_size=3000 * MIB)
    )
    said = read_limited(path)
    assert said.startswith("CorruptFileError"), said
    assert "bomb.bag" in said and "decompression bomb" in said and "200×" in said


def test_a_bz2_bag_chunk_expanding_beyond_its_claim_stops_at_the_claim(tmp_path, short):
    time_ns, accel = short
    messages = imu_messages(time_ns, accel, ros1=True)
    data = bz2_zeros(3000)
    path = tmp_path / "liar.bag"
    claim = 100 * len(data)  # plausible (100×), but the streams hold 3000 MiB
    path.write_bytes(
        raw_bag(time_ns, messages, compression="bz2", chunk_data=data, chunk_size=claim)
    )
    said = read_limited(path)
    assert said.startswith("CorruptFileError") and "decompresses to more than" in said, said


def test_an_lz4_bag_chunk_of_a_gibibyte_is_refused(tmp_path, short):
    time_ns, accel = short
    data = lz4_zeros(1024 * MIB)
    path = tmp_path / "lz4bomb.bag"
    messages = imu_messages(time_ns, accel, ros1=True)
    path.write_bytes(
        raw_bag(time_ns, messages, compression="lz4", chunk_data=data, chunk_size=1024 * MIB)
    )
    said = read_limited(path)
    assert said.startswith("CorruptFileError") and "decompression bomb" in said, said


def _zstd_bag(tmp_path, short, name: str, bomb: bytes):
    """A rosbag2 folder with per-message zstd whose first message is ``bomb``."""
    time_ns, accel = short
    db3 = write_db3(tmp_path / name, time_ns, imu_messages(time_ns, accel), zstd_messages=True)
    with sqlite3.connect(db3) as db:
        db.execute(
            "UPDATE messages SET data = ? WHERE id = (SELECT MIN(id) FROM messages)", (bomb,)
        )
    return db3.parent


def _zstd_frame_declaring(size: int) -> bytes:
    """A zstd frame whose header declares ``size`` bytes but which holds 16 raw bytes."""
    descriptor = bytes([0xE0])  # 8-byte content size, single segment, no checksum
    block = ((16 << 3) | 1).to_bytes(3, "little")  # the last block, raw, 16 bytes
    return b"\x28\xb5\x2f\xfd" + descriptor + size.to_bytes(8, "little") + block + bytes(16)


@pytest.mark.parametrize(
    "name, bomb, said",
    [
        ("sized", lambda: zstd_zeros(1024 * MIB, True), "declares 1073741824 bytes"),
        ("unsized", lambda: zstd_zeros(1024 * MIB, False), "decompress to more than"),
        ("six_gb", lambda: _zstd_frame_declaring(6_000_000_000), "declares 6000000000 bytes"),
    ],
)
def test_a_zstd_message_bomb_in_a_rosbag2_is_refused(tmp_path, short, name, bomb, said):
    folder = _zstd_bag(tmp_path, short, name, bomb())
    text = read_limited(folder)
    assert text.startswith("CorruptFileError"), text
    assert str(folder) in text and "message row" in text and said in text


def test_real_bz2_and_zstd_data_pass(tmp_path, short):
    time_ns, accel = short
    bag = tmp_path / "ok.bag"
    bag.write_bytes(raw_bag(time_ns, imu_messages(time_ns, accel, ros1=True), compression="bz2"))
    np.testing.assert_array_equal(read_recording(bag).accel_mps2, accel)
    db3 = write_db3(tmp_path / "z", time_ns, imu_messages(time_ns, accel), zstd_messages=True)
    np.testing.assert_array_equal(read_recording(db3.parent).accel_mps2, accel)


# --- item 3: malformed fields, named ------------------------------------------------------


@pytest.mark.parametrize(
    "kind, field",
    [
        ("connection", "conn"),
        ("chunk", "size"),
        ("chunk info", "chunk_pos"),
        ("index data", "count"),
    ],
)
def test_a_bag_record_missing_a_field_is_named(tmp_path, short, kind, field):
    time_ns, accel = short
    path = tmp_path / "bad.bag"
    path.write_bytes(raw_bag(time_ns, imu_messages(time_ns, accel, ros1=True), drop={kind: field}))
    with pytest.raises(
        CorruptFileError,
        match=rf"bad\.bag: byte \d+: the {kind} record's header has no '{field}' field",
    ):
        read_recording(path)


def test_a_bag_field_of_the_wrong_width_is_named(tmp_path, short):
    time_ns, accel = short
    messages = imu_messages(time_ns, accel, ros1=True)
    data = raw_bag(time_ns, messages, values={"connection": {"conn": b"\x00\x00"}})
    path = tmp_path / "wide.bag"
    path.write_bytes(data)
    with pytest.raises(CorruptFileError, match=r"'conn' field holds \d+ bytes, not 4"):
        read_recording(path)


def test_a_ros_bag_of_format_1_2_is_named_as_such(tmp_path, capsys):
    path = tmp_path / "old.bag"
    path.write_bytes(b"#ROSBAG V1.2\n" + bytes(4096))
    with pytest.raises(
        NotMcapError, match=r"old\.bag: a ROS bag of format 1\.2; wheelcal reads format 2\.0"
    ):
        read_recording(path)
    assert main(["calibrate", str(path), "--out", str(tmp_path / "o"), "--radius", "0.28"]) == 1
    err = capsys.readouterr().err
    assert "format 1.2" in err and "MCAP" not in err


def _db3(tmp_path, short, name="cells"):
    time_ns, accel = short
    return write_db3(tmp_path / name, time_ns, imu_messages(time_ns, accel))


@pytest.mark.parametrize(
    "sql, said",
    [
        (
            "UPDATE messages SET timestamp = NULL WHERE id = 7",
            r"row with id 7 \(topic '/imu/data_raw'\): timestamp is NULL, not an integer",
        ),
        (
            "UPDATE messages SET data = NULL WHERE id = 9",
            r"row with id 9 .*: data is NULL, not a blob",
        ),
        (
            "UPDATE messages SET data = 'text' WHERE id = 3",
            r"row with id 3 .*: data is the text 'text', not a blob",
        ),
        (
            "UPDATE messages SET timestamp = 'soon' WHERE id = 5",
            r"row with id 5 .*: timestamp is the text 'soon'",
        ),
        ("UPDATE topics SET type = NULL", r"row with id 1: type is NULL, not text"),
    ],
)
def test_db3_cells_null_or_of_the_wrong_type_are_named(tmp_path, short, sql, said):
    db3 = _db3(tmp_path, short)
    with sqlite3.connect(db3) as db:
        for table in ("messages", "topics"):  # as another tool may write them: no NOT NULL
            db.execute(f"CREATE TABLE loose AS SELECT * FROM {table}")
            db.execute(f"DROP TABLE {table}")
            db.execute(f"ALTER TABLE loose RENAME TO {table}")
        db.execute(sql)
    with pytest.raises(
        CorruptFileError, match=rf"cells\.db3: the (messages|topics) table's {said}"
    ):
        read_recording(db3)


def test_a_metadata_yaml_that_is_not_utf8_is_named(tmp_path, short, capsys):
    db3 = _db3(tmp_path, short, "folder")
    meta = db3.parent / "metadata.yaml"
    meta.write_bytes(
        meta.read_bytes().replace(b"rosbag2_bagfile_information", b"rosbag2_\xff\xfe", 1)
    )
    with pytest.raises(
        CorruptFileError, match=r"folder/metadata\.yaml: is not UTF-8 text \(byte \d+"
    ):
        read_recording(db3.parent)


def test_two_mcap_channels_with_one_id_are_named_as_the_clash(tmp_path, short):
    time_ns, accel = short
    payloads = imu_messages(time_ns, accel)
    schema = mcap_record(
        0x03,
        (1).to_bytes(2, "little")
        + mcap_string("sensor_msgs/msg/Imu")
        + mcap_string("ros2msg")
        + mcap_string(""),
    )

    def channel(topic):
        return mcap_record(
            0x04,
            (1).to_bytes(2, "little")
            + (1).to_bytes(2, "little")
            + mcap_string(topic)
            + mcap_string("cdr")
            + bytes(4),
        )

    def message(seq, ns, data):
        head = (1).to_bytes(2, "little") + seq.to_bytes(4, "little") + ns.to_bytes(8, "little") * 2
        return mcap_record(0x05, head + data)

    half = len(payloads) // 2
    body = [schema, channel("/imu/a")]
    body += [message(i, int(time_ns[i]), payloads[i]) for i in range(half)]
    body += [channel("/imu/b")]
    body += [message(i, int(time_ns[i - half]), payloads[i]) for i in range(half, len(payloads))]
    header = mcap_record(0x01, mcap_string("ros2") + mcap_string("merged"))
    data = (
        MAGIC
        + header
        + b"".join(body)
        + mcap_record(0x0F, bytes(4))
        + mcap_record(0x02, bytes(20))
        + MAGIC
    )
    path = tmp_path / "merged.mcap"
    path.write_bytes(data)
    with pytest.raises(
        CorruptFileError,
        match=r"merged\.mcap: data section, byte \d+: channel id 1 is defined twice, as topic "
        r"'/imu/a' and topic '/imu/b': their messages cannot be told apart",
    ):
        read_recording(path)


def test_the_calibrate_command_names_a_bag_field_not_a_key_error(tmp_path, short, capsys):
    time_ns, accel = short
    path = tmp_path / "nochunkpos.bag"
    path.write_bytes(
        raw_bag(time_ns, imu_messages(time_ns, accel, ros1=True), drop={"chunk info": "chunk_pos"})
    )
    assert main(["calibrate", str(path), "--out", str(tmp_path / "o"), "--radius", "0.28"]) == 1
    err = capsys.readouterr().err
    assert "no 'chunk_pos' field" in err and "KeyError" not in err and "unexpected" not in err
