"""MCAP reading and writing: round trips, both encodings, topics, metadata, copies, atomicity.

Files are generated into pytest's tmp_path from the simulator (Table II bench).
"""

import json
import os
import struct

import numpy as np
import pytest
from mcap.writer import IndexType

from wheelcal.io import (
    CsvLayout,
    InputError,
    MetadataError,
    TopicError,
    accel_channel,
    atomic_write_bytes,
    atomic_write_text,
    convert_csv,
    copy_with_channels,
    list_accel_topics,
    read_recording,
    write_accel_mcap,
    write_recording,
)
from wheelcal.io.imu_cdr import IMU_MSGDEF, encode_imu_messages
from wheelcal.io.mcap_writer import ChannelData, recording_stamps_ns, write_channels
from wheelcal.recording import SessionInfo
from wheelcal.simulate import Quantiser, Scenario, simulate, table2

G = 9.80665


@pytest.fixture(scope="module")
def session():
    base = table2(rng=np.random.default_rng(3))
    info = SessionInfo(
        radius_m=0.28,
        radius_std_m=0.0005,
        sensor_id="imu-7",
        mounting_id="rim-A",
        gravity_mps2=9.8062,
        extra=(("operator", "kim"),),
    )
    scenario = Scenario(truth=base.truth, duration_s=20.0, rate_hz=200.0, info=info)
    return simulate(scenario, np.random.default_rng(4), epoch_unix_ns=1_712_345_678_901_234_567)


def _same(a, b):
    np.testing.assert_array_equal(a.accel_mps2, b.accel_mps2)
    np.testing.assert_array_equal(recording_stamps_ns(a), recording_stamps_ns(b))
    assert a.info == b.info


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
@pytest.mark.parametrize(("encoding", "batch"), [("ros2", 1), ("json", 1), ("json", 7)])
def test_round_trip_is_exact(session, tmp_path, encoding, batch, compression):
    path = tmp_path / "rt.mcap"
    write_recording(
        session.recording, path, encoding=encoding, batch_size=batch, compression=compression
    )
    back = read_recording(path)
    _same(back, session.recording)
    assert back.source == str(path)
    assert back.topic in ("/imu/data_raw", "/wheelcal/accel")
    assert back.notes == ()


def test_quantised_round_trip(tmp_path):
    base = table2(rng=np.random.default_rng(5))
    scenario = Scenario(
        truth=base.truth, duration_s=15.0, quantiser=Quantiser(full_scale_g=16, bits=16)
    )
    rec = simulate(scenario, np.random.default_rng(6)).recording
    for encoding in ("ros2", "json"):
        write_recording(rec, tmp_path / "q.mcap", encoding=encoding, batch_size=25)
        back = read_recording(tmp_path / "q.mcap")
        np.testing.assert_array_equal(back.accel_mps2, rec.accel_mps2)


def test_session_metadata_and_overrides(session, tmp_path):
    path = tmp_path / "s.mcap"
    write_recording(session.recording, path)
    info = read_recording(path).info
    assert (info.radius_m, info.sensor_id, info.gravity_mps2) == (0.28, "imu-7", 9.8062)
    assert dict(info.extra) == {"operator": "kim"}
    over = read_recording(path, info_overrides={"radius_m": 0.3, "sensor_id": None}).info
    assert over.radius_m == 0.3 and over.sensor_id == "imu-7"
    with pytest.raises(MetadataError, match=r"s\.mcap: unknown session override.*radus_m"):
        read_recording(path, info_overrides={"radus_m": 0.3})
    # Pipeline defaults fill only what neither the file nor the command line gives.
    defaults = {"mounting_id": "default", "full_scale_g": 16, "radius_m": 0.5}
    info = read_recording(path, info_overrides={"radius_m": 0.3}, info_defaults=defaults).info
    assert (info.mounting_id, info.full_scale_g, info.radius_m) == ("rim-A", 16.0, 0.3)


def test_reads_files_of_the_reference_ros2_writer(session, tmp_path):
    """An independent writer (mcap_ros2) with a longer frame_id and its own layout."""
    from mcap_ros2.writer import Writer

    path = tmp_path / "ref.mcap"
    stamps = recording_stamps_ns(session.recording)
    with open(path, "wb") as stream:
        writer = Writer(stream)
        schema = writer.register_msgdef("sensor_msgs/msg/Imu", IMU_MSGDEF)
        for stamp, (x, y, z) in zip(
            stamps[:2400].tolist(), session.recording.accel_mps2[:2400], strict=True
        ):
            sec, nsec = divmod(stamp, 1_000_000_000)
            writer.write_message(
                "/imu",
                schema,
                {
                    "header": {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": "imu_link_17"},
                    "linear_acceleration": {"x": x, "y": y, "z": z},
                },
                log_time=stamp + 12345,
            )
        writer.add_metadata("wheelcal.session", {"radius_m": "0.28"})
        writer.finish()
    back = read_recording(path)
    np.testing.assert_array_equal(back.accel_mps2, session.recording.accel_mps2[:2400])
    np.testing.assert_array_equal(recording_stamps_ns(back), stamps[:2400])


def test_zero_stamps_fall_back_to_log_time(tmp_path):
    n = 3000
    stamps = 1_700_000_000_000_000_000 + np.arange(n) * 5_000_000
    accel = np.tile([0.1, 0.2, G], (n, 1)) + np.random.default_rng(0).normal(0, 0.05, (n, 3))
    payloads = encode_imu_messages(np.zeros(n, np.int64), accel, "imu")
    channel = ChannelData(
        topic="/imu",
        schema_name="sensor_msgs/msg/Imu",
        schema_encoding="ros2msg",
        schema_data=IMU_MSGDEF.encode(),
        message_encoding="cdr",
        messages=tuple(zip(stamps.tolist(), payloads, strict=True)),
    )
    write_channels(tmp_path / "z.mcap", [channel])
    back = read_recording(tmp_path / "z.mcap")
    np.testing.assert_array_equal(recording_stamps_ns(back), stamps)
    assert any("zero header.stamp" in note for note in back.notes)


def test_big_endian_cdr(tmp_path):
    n = 2500
    stamps = 1_700_000_000_000_000_000 + np.arange(n) * 5_000_000
    rng = np.random.default_rng(1)
    accel = np.tile([0.3, -0.2, G], (n, 1)) + rng.normal(0, 0.05, (n, 3))
    messages = []
    for stamp, row in zip(stamps.tolist(), accel, strict=True):
        sec, nsec = divmod(stamp, 1_000_000_000)
        body = struct.pack(">iII", sec, nsec, 4) + b"imu\x00"  # 16 bytes: q = 16
        body += struct.pack(">4d", 0, 0, 0, 1) + struct.pack(">9d", -1, *[0] * 8)
        body += struct.pack(">3d", 0, 0, 0) + struct.pack(">9d", -1, *[0] * 8)
        body += struct.pack(">3d", *row) + struct.pack(">9d", *[0] * 9)
        messages.append((stamp, b"\x00\x00\x00\x00" + body))
    channel = ChannelData(
        "/imu", "sensor_msgs/msg/Imu", "ros2msg", IMU_MSGDEF.encode(), "cdr", tuple(messages)
    )
    write_channels(tmp_path / "be.mcap", [channel])
    back = read_recording(tmp_path / "be.mcap")
    np.testing.assert_array_equal(back.accel_mps2, accel)


def test_unchunked_and_unindexed_files(session, tmp_path):
    from mcap.writer import Writer

    rec = session.recording
    channel = accel_channel(recording_stamps_ns(rec), rec.accel_mps2, encoding="ros2")
    other = accel_channel(
        recording_stamps_ns(rec)[::3], rec.accel_mps2[::3], encoding="json", topic="/other"
    )
    for chunking, index in [(False, IndexType.ALL), (True, IndexType.NONE)]:
        path = tmp_path / f"u{chunking}.mcap"
        with open(path, "wb") as stream:
            writer = Writer(stream, use_chunking=chunking, index_types=index)
            writer.start()
            ids = []
            for ch in (channel, other):
                sid = writer.register_schema(ch.schema_name, ch.schema_encoding, ch.schema_data)
                ids.append(writer.register_channel(ch.topic, ch.message_encoding, sid))
            # Interleave the two channels (different message sizes).
            merged = sorted(
                [(t, ids[0], d) for t, d in channel.messages]
                + [(t, ids[1], d) for t, d in other.messages],
                key=lambda m: m[0],
            )
            for t, cid, data in merged:
                writer.add_message(cid, t, data, t)
            writer.finish()
        back = read_recording(path, topic="/imu/data_raw")
        np.testing.assert_array_equal(back.accel_mps2, rec.accel_mps2)
        assert read_recording(path, topic="/other").samples == len(other.messages)
    # One fixed-size channel without indexes: the record walk gallops over the chunks.
    path = tmp_path / "gallop.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream, index_types=IndexType.NONE, chunk_size=200_000)
        writer.start()
        sid = writer.register_schema(channel.schema_name, "ros2msg", channel.schema_data)
        cid = writer.register_channel(channel.topic, "cdr", sid)
        for t, data in channel.messages:
            writer.add_message(cid, t, data, t)
        writer.finish()
    np.testing.assert_array_equal(read_recording(path).accel_mps2, rec.accel_mps2)


def test_json_in_g_is_converted(session, tmp_path):
    rec = session.recording
    write_accel_mcap(
        tmp_path / "g.mcap",
        recording_stamps_ns(rec),
        rec.accel_mps2 / G,
        encoding="json",
        unit="g",
        batch_size=20,
        info=rec.info,
    )
    back = read_recording(tmp_path / "g.mcap")
    np.testing.assert_allclose(back.accel_mps2, rec.accel_mps2, rtol=1e-15, atol=1e-14)
    assert any("converted from g" in note for note in back.notes)


def test_pretty_printed_json_takes_the_exact_path(session, tmp_path):
    rec = session.recording
    stamps = recording_stamps_ns(rec)
    messages = tuple(
        (
            int(stamps[i + 9]),
            json.dumps(
                {
                    "accel": rec.accel_mps2[i : i + 10].tolist(),
                    "timestamps_ns": stamps[i : i + 10].tolist(),
                },
                indent=2,
            ).encode(),
        )
        for i in range(0, rec.samples - 9, 10)
    )
    base = accel_channel(stamps, rec.accel_mps2, encoding="json")
    channel = ChannelData(
        base.topic, base.schema_name, base.schema_encoding, base.schema_data, "json", messages
    )
    write_channels(tmp_path / "p.mcap", [channel])
    back = read_recording(tmp_path / "p.mcap")
    np.testing.assert_array_equal(back.accel_mps2, rec.accel_mps2[: back.samples])


def test_topic_choice(session, tmp_path):
    rec = session.recording
    stamps = recording_stamps_ns(rec)
    channels = [
        accel_channel(stamps, rec.accel_mps2, encoding="ros2", topic="/imu/a"),
        accel_channel(stamps, rec.accel_mps2 * 1.01, encoding="json", topic="/imu/b"),
    ]
    path = tmp_path / "two.mcap"
    write_channels(path, channels)
    assert [t.topic for t in list_accel_topics(path)] == ["/imu/a", "/imu/b"]
    with pytest.raises(
        TopicError, match=r"two\.mcap: several accelerometer topics.*/imu/a.*/imu/b"
    ):
        read_recording(path)
    np.testing.assert_array_equal(
        read_recording(path, topic="/imu/b").accel_mps2, rec.accel_mps2 * 1.01
    )
    with pytest.raises(TopicError, match=r"two\.mcap: there is no topic '/imu/c'.*/imu/a"):
        read_recording(path, topic="/imu/c")


def test_copy_keeps_everything_and_adds_a_channel(session, tmp_path):
    rec = session.recording
    src = tmp_path / "src.mcap"
    stamps = recording_stamps_ns(rec)
    extra = ChannelData(
        "/notes", "demo.Note", "jsonschema", b"{}", "json", ((int(stamps[5]), b'{"n": 1}'),)
    )
    write_channels(
        src,
        [accel_channel(stamps, rec.accel_mps2), extra],
        {"wheelcal.session": {"radius_m": "0.28"}, "site": {"room": "lab 2"}},
    )
    dst = tmp_path / "dst.mcap"
    calibrated = accel_channel(stamps, rec.accel_mps2 * 0.5, topic="/imu/calibrated")
    copy_with_channels(src, dst, [calibrated], {"wheelcal.calibration": {"file": "cal.json"}})

    from mcap.reader import make_reader

    def summary(path):
        with open(path, "rb") as stream:
            reader = make_reader(stream, validate_crcs=True)
            topics = {}
            for _, channel, message in reader.iter_messages():
                topics.setdefault(channel.topic, []).append(message.data)
            return topics, {m.name: m.metadata for m in reader.iter_metadata()}

    before, _ = summary(src)
    after, meta_after = summary(dst)
    for topic, payloads in before.items():
        assert after[topic] == payloads
    assert set(after) == set(before) | {"/imu/calibrated"}
    assert meta_after["site"] == {"room": "lab 2"}
    assert meta_after["wheelcal.calibration"] == {"file": "cal.json"}
    np.testing.assert_array_equal(
        read_recording(dst, topic="/imu/calibrated").accel_mps2, rec.accel_mps2 * 0.5
    )
    with pytest.raises(ValueError, match="'/imu/data_raw' already exists"):
        copy_with_channels(src, tmp_path / "x.mcap", [accel_channel(stamps, rec.accel_mps2)])
    with pytest.raises(ValueError, match="'/imu/calibrated' already exists"):
        copy_with_channels(src, tmp_path / "x.mcap", [calibrated, calibrated])
    assert not (tmp_path / "x.mcap").exists()
    with pytest.raises(ValueError, match="must not overwrite its source"):
        copy_with_channels(src, src, [calibrated])


def _listing(directory):
    return sorted(os.listdir(directory))


def test_atomic_writes_leave_nothing_behind_on_error(session, tmp_path, monkeypatch):
    atomic_write_text(tmp_path / "a.txt", "hello")
    atomic_write_bytes(tmp_path / "b.bin", b"\x00\x01")
    assert (tmp_path / "a.txt").read_text() == "hello"
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\x01"

    import mcap.writer

    def broken(self, *args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(mcap.writer.Writer, "add_message", broken)
    with pytest.raises(OSError, match="disk full"):
        write_recording(session.recording, tmp_path / "c.mcap")
    assert _listing(tmp_path) == ["a.txt", "b.bin"]
    # An existing file is left as it was.
    (tmp_path / "d.mcap").write_bytes(b"old")
    with pytest.raises(OSError, match="disk full"):
        write_recording(session.recording, tmp_path / "d.mcap")
    assert (tmp_path / "d.mcap").read_bytes() == b"old"
    assert _listing(tmp_path) == ["a.txt", "b.bin", "d.mcap"]


def test_csv_conversion(session, tmp_path):
    rec = session.recording
    stamps = recording_stamps_ns(rec)
    lines = ["# logger v2", "time_ms;x;y;z"]
    for stamp, (x, y, z) in zip(stamps.tolist(), (rec.accel_mps2 / G).tolist(), strict=True):
        ms = f"{stamp // 1_000_000}.{stamp % 1_000_000:06d}"
        lines.append(f"{ms};{x!r};{y!r};{z!r}")
    csv_path = tmp_path / "log.csv"
    csv_path.write_text("\n".join(lines) + "\n")
    layout = CsvLayout("time_ms", ("x", "y", "z"), time_unit="ms", accel_unit="g")
    for encoding in ("json", "ros2"):
        out = tmp_path / f"log_{encoding}.mcap"
        report = convert_csv(csv_path, out, layout, encoding=encoding, session={"radius_m": "0.31"})
        assert report.samples == rec.samples and report.skipped_rows == 0
        back = read_recording(out)
        np.testing.assert_array_equal(recording_stamps_ns(back), stamps)  # exact from decimals
        np.testing.assert_allclose(back.accel_mps2, rec.accel_mps2, rtol=1e-15, atol=1e-14)
        assert back.info.radius_m == 0.31

    # Without a header, by column index, time in seconds relative to an epoch.
    plain = tmp_path / "plain.csv"
    rows = [f"{i / 200},{a},{b},{c}" for i, (a, b, c) in enumerate(rec.accel_mps2.tolist())]
    plain.write_text("\n".join(rows))
    convert_csv(
        plain,
        tmp_path / "plain.mcap",
        CsvLayout(0, (1, 2, 3), accel_unit="m/s^2", epoch_unix_ns=1_700_000_000_000_000_000),
    )
    back = read_recording(tmp_path / "plain.mcap")
    assert back.epoch_unix_ns == 1_700_000_000_000_000_000
    np.testing.assert_allclose(back.time_s, rec.time_s, atol=1e-9)


def test_csv_errors_name_the_file_and_write_nothing(tmp_path):
    csv_path = tmp_path / "bad.csv"
    csv_path.write_text("t,ax,ay\n0,1,2\n")
    with pytest.raises(InputError, match=r"bad\.csv: no column 'az'"):
        convert_csv(csv_path, tmp_path / "out.mcap")
    csv_path.write_text("t,ax,ay,az\n0,1,2,3\n0.1,1,oops,3\n")
    with pytest.raises(InputError, match=r"bad\.csv: data row 3: .* not a number"):
        convert_csv(csv_path, tmp_path / "out.mcap")
    with pytest.raises(InputError, match=r"missing\.csv: no such file"):
        convert_csv(tmp_path / "missing.csv", tmp_path / "out.mcap")
    assert _listing(tmp_path) == ["bad.csv"]


def test_ros2_channels_decode_with_the_reference_decoder(tmp_path):
    """mcap_ros2 parses the message definitions wheelcal stores and reads the same values."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from wheelcal.io.mcap_writer import temperature_channel

    stamps = 1_712_345_678_000_000_000 + np.arange(40, dtype=np.int64) * 5_000_000
    accel = np.random.default_rng(2).normal(0.0, 9.8, size=(40, 3))
    gyro = accel[:, ::-1] * 0.1
    gyro[5] = np.nan  # no reading: covariance[0] = -1
    temperature = 20.0 + 0.01 * np.arange(40)
    path = tmp_path / "ros2.mcap"
    write_channels(
        path,
        [
            accel_channel(stamps, accel, gyro=gyro, frame_id="a_longer_frame"),
            temperature_channel(stamps, temperature, frame_id="t"),
        ],
    )
    seen = {"/imu/data_raw": [], "/imu/temperature": []}
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, channel, _, msg in reader.iter_decoded_messages():
            seen[channel.topic].append(msg)
    imu, temp = seen["/imu/data_raw"], seen["/imu/temperature"]
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in imu] == stamps.tolist()
    assert {m.header.frame_id for m in imu} == {"a_longer_frame"}
    got = np.array(
        [[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z] for m in imu]
    )
    np.testing.assert_array_equal(got, accel)
    rate = np.array(
        [[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in imu]
    )
    absent = np.array([m.angular_velocity_covariance[0] == -1.0 for m in imu])
    assert np.flatnonzero(absent).tolist() == [5]
    np.testing.assert_array_equal(rate[~absent], gyro[~absent])
    np.testing.assert_array_equal([m.temperature for m in temp], temperature)
    assert [m.header.frame_id for m in temp] == ["t"] * 40
