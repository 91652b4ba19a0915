"""Issue 16, the reading side: hostile files are refused cleanly, damaged samples repaired.

Every file here is built in the test: decompression bombs from raw MCAP
records (the readers are run in a subprocess with a data-segment limit, so a
regression fails the test instead of exhausting the machine), the other
defects with wheelcal's own writer.
"""

import os
import zlib

import numpy as np
import pytest

from bombs import MIB, lz4_zeros, mcap_record, mcap_string, read_limited, zstd_zeros
from wheelcal.io import CorruptFileError, InputError, read_recording, write_accel_mcap
from wheelcal.io.mcap_scan import MAGIC
from wheelcal.io.mcap_writer import recording_stamps_ns

# --- raw MCAP records -------------------------------------------------------------------


def _chunk(compression: str, data: bytes, claimed_size: int, crc: int = 0) -> bytes:
    content = (
        (0).to_bytes(8, "little")
        + (0).to_bytes(8, "little")
        + claimed_size.to_bytes(8, "little")
        + crc.to_bytes(4, "little")
        + mcap_string(compression)
        + len(data).to_bytes(8, "little")
        + data
    )
    return mcap_record(0x06, content)


def _mcap(*records: bytes) -> bytes:
    header = mcap_record(0x01, mcap_string("") + mcap_string("hostile"))
    data_end = mcap_record(0x0F, (0).to_bytes(4, "little"))
    footer = mcap_record(0x02, bytes(20))
    return MAGIC + header + b"".join(records) + data_end + footer + MAGIC


def _zeros_crc(size: int) -> int:
    crc, block = 0, bytes(MIB)
    for _ in range(size // MIB):
        crc = zlib.crc32(block, crc)
    return crc


# --- item 3: decompression bombs --------------------------------------------------------


def test_zstd_bomb_with_a_true_size_and_crc_is_refused_before_allocating(tmp_path):
    size = 512 * MIB
    data = zstd_zeros(size, content_size=True)
    assert len(data) < 64 * 1024  # 16 KB of file, 512 MiB of zeros
    path = tmp_path / "bomb.mcap"
    path.write_bytes(_mcap(_chunk("zstd", data, size, _zeros_crc(size))))
    said = read_limited(path)
    assert said.startswith("CorruptFileError")
    assert "bomb.mcap" in said and "decompression bomb" in said


def test_zstd_chunk_without_content_size_claiming_a_tebibyte(tmp_path):
    data = zstd_zeros(64 * MIB, content_size=False)
    path = tmp_path / "tib.mcap"
    path.write_bytes(_mcap(_chunk("zstd", data, 1 << 40)))
    said = read_limited(path)
    assert said.startswith("CorruptFileError") and "claims 1099511627776 bytes" in said


def test_zstd_chunk_that_expands_beyond_its_claim_stops_at_the_claim(tmp_path):
    data = zstd_zeros(256 * MIB, content_size=False)
    claimed = 100 * len(data)  # plausible, but the frame holds far more
    path = tmp_path / "more.mcap"
    path.write_bytes(_mcap(_chunk("zstd", data, claimed)))
    with pytest.raises(CorruptFileError, match=r"more\.mcap: .*decompresses to more than"):
        read_recording(path)


def test_lz4_bomb_is_refused_before_decompressing(tmp_path):
    size = 1024 * MIB
    data = lz4_zeros(size)
    path = tmp_path / "lz4bomb.mcap"
    path.write_bytes(_mcap(_chunk("lz4", data, size)))
    assert path.stat().st_size < 8 * MIB
    said = read_limited(path)
    assert said.startswith("CorruptFileError") and "decompression bomb" in said


def test_lz4_chunk_that_expands_beyond_its_claim_stops_at_the_claim(tmp_path):
    data = lz4_zeros(64 * MIB)
    path = tmp_path / "lz4more.mcap"
    path.write_bytes(_mcap(_chunk("lz4", data, 2 * len(data))))
    with pytest.raises(CorruptFileError, match=r"lz4more\.mcap: .*decompresses to more than"):
        read_recording(path)


def test_real_chunks_stay_far_below_the_ratio_limit(tmp_path):
    """An exactly constant sensor at rest, the best case for the compressors."""
    from wheelcal.io.mcap_scan import MAX_CHUNK_RATIO

    n = 20_000
    stamps = 1_700_000_000_000_000_000 + 5_000_000 * np.arange(n, dtype=np.int64)
    accel = np.tile([0.0, 0.0, 9.80665], (n, 1))
    for compression in ("zstd", "lz4"):
        path = tmp_path / f"rest-{compression}.mcap"
        write_accel_mcap(path, stamps, accel, compression=compression)
        from mcap.records import Chunk
        from mcap.stream_reader import StreamReader

        with open(path, "rb") as stream:
            ratios = [
                rec.uncompressed_size / len(rec.data)
                for rec in StreamReader(stream, emit_chunks=True).records
                if isinstance(rec, Chunk)
            ]
        assert max(ratios) < MAX_CHUNK_RATIO / 4


# --- samples: the short session of conftest.py's `base` -----------------------------------


def _write(tmp_path, stamps, accel, name="hostile.mcap", **kwargs):
    kwargs.setdefault("session", {"radius_m": "0.28"})
    path = tmp_path / name
    write_accel_mcap(path, stamps, accel, **kwargs)
    return path


DAY_NS = 86_400 * 10**9


# --- item 1: isolated late timestamps ---------------------------------------------------


@pytest.mark.parametrize(
    ("where", "shift_ns"),
    [
        (1500, DAY_NS),  # one stamp a day late, mid-file
        (1500, 11 * DAY_NS),  # 11 days late
        (-1, DAY_NS),  # the last stamp a day late
        (0, -(1 << 30) * 10**9),  # bit 30 of the first stamp's sec flipped (1.7e9 has it set)
        (2500, (1 << 20) * 10**9),  # bit 20 of sec flipped, mid-file
        (2500, 300_000_000),  # 0.3 s late: it would land among other samples
    ],
)
def test_isolated_stray_stamps_are_dropped_with_a_note(tmp_path, base, where, shift_ns):
    stamps, accel = base
    bad = stamps.copy()
    bad[where] += shift_ns
    rec = read_recording(_write(tmp_path, bad, accel))
    keep = np.ones(stamps.size, bool)
    keep[where] = False
    np.testing.assert_array_equal(recording_stamps_ns(rec), stamps[keep])
    np.testing.assert_array_equal(rec.accel_mps2, accel[keep])
    note = next(n for n in rec.notes if "stray timestamps" in n)
    assert note.startswith("dropped 1 sample(s)")
    assert not any("gap" in n for n in rec.notes)


def test_a_stray_batch_of_json_stamps_is_dropped(tmp_path, base):
    stamps, accel = base
    bad = stamps.copy()
    bad[1000:1010] += 5 * DAY_NS  # one message of 10 samples with a corrupt clock
    rec = read_recording(_write(tmp_path, bad, accel, encoding="json", batch_size=10))
    assert rec.samples == stamps.size - 10
    assert any(n.startswith("dropped 10 sample(s) with stray") for n in rec.notes)


def test_a_delayed_packet_that_fills_its_hole_is_sorted_not_dropped(tmp_path, base):
    stamps, accel = base
    order = np.arange(stamps.size)
    late = order[1000:1010].copy()  # written 2 s after it was sampled
    order = np.concatenate([order[:1000], order[1010:1410], late, order[1410:]])
    rec = read_recording(_write(tmp_path, stamps[order], accel[order]))
    np.testing.assert_array_equal(recording_stamps_ns(rec), stamps)
    np.testing.assert_array_equal(rec.accel_mps2, accel)
    assert not any("stray" in n for n in rec.notes)


def test_a_recording_that_resumes_after_a_real_gap_keeps_its_first_samples(tmp_path, base):
    stamps, accel = base
    early = stamps.copy()
    early[:5] -= 10 * 10**9  # five samples, then the link was down for 10 s
    rec = read_recording(_write(tmp_path, early, accel))
    assert rec.samples == stamps.size
    assert any("gap" in n for n in rec.notes)


# --- item 5: messages out of order -------------------------------------------------------


def test_pairwise_swapped_messages_are_sorted(tmp_path, base):
    stamps, accel = base
    order = np.arange(stamps.size - stamps.size % 2).reshape(-1, 2)[:, ::-1].reshape(-1)
    rec = read_recording(_write(tmp_path, stamps[order], accel[order]))
    np.testing.assert_array_equal(recording_stamps_ns(rec), stamps[np.sort(order)])
    np.testing.assert_array_equal(rec.accel_mps2, accel[np.sort(order)])
    assert any(f"sorted {order.size // 2} out-of-order" in n for n in rec.notes)


def test_writer_threads_a_few_messages_apart_are_sorted(tmp_path, base):
    stamps, accel = base
    rng = np.random.default_rng(3)
    order = np.argsort(np.arange(stamps.size) + rng.uniform(0, 8, stamps.size), kind="stable")
    rec = read_recording(_write(tmp_path, stamps[order], accel[order]))
    np.testing.assert_array_equal(recording_stamps_ns(rec), stamps)
    assert any("out-of-order timestamp steps into time order" in n for n in rec.notes)


# --- item 7: gross outliers ---------------------------------------------------------------


def _read_strict(path, **kwargs):
    """read_recording with every numpy / Python warning turned into an error."""
    import warnings

    with warnings.catch_warnings(), np.errstate(all="raise"):
        warnings.simplefilter("error")
        return read_recording(path, **kwargs)


def test_a_single_huge_sample_is_dropped_without_warnings(tmp_path, base):
    stamps, accel = base
    bad = accel.copy()
    bad[2000, 1] = 1e300
    rec = _read_strict(_write(tmp_path, stamps, bad))
    keep = np.arange(stamps.size) != 2000
    np.testing.assert_array_equal(rec.accel_mps2, accel[keep])
    note = next(n for n in rec.notes if "gross outlier" in n)
    assert note.startswith("dropped 1 gross outlier") and "1e+300" in note


def test_twenty_spikes_of_200_mps2_are_dropped(tmp_path, base):
    stamps, accel = base
    bad = accel.copy()
    where = np.random.default_rng(4).choice(np.arange(100, stamps.size - 100), 20, replace=False)
    bad[where, 0] += 200.0
    rec = read_recording(_write(tmp_path, stamps, bad))
    keep = np.ones(stamps.size, bool)
    keep[where] = False
    np.testing.assert_array_equal(rec.accel_mps2, accel[keep])
    assert any(n.startswith("dropped 20 gross outlier") for n in rec.notes)


def test_a_pair_of_adjacent_glitches_is_dropped(tmp_path, base):
    stamps, accel = base
    bad = accel.copy()
    bad[3000:3002, 2] = -500.0
    rec = read_recording(_write(tmp_path, stamps, bad))
    assert rec.samples == stamps.size - 2
    assert any(n.startswith("dropped 2 gross outlier") for n in rec.notes)


def test_a_huge_sample_no_longer_shrinks_the_window(tmp_path):
    """The issue's case: one 1e300 sample shrank the free-spin window from 87 s to 31 s."""
    from wheelcal import api
    from wheelcal.simulate.hostile import clean

    rec = clean(np.random.default_rng(5), duration_s=40.0).recording
    stamps = recording_stamps_ns(rec)
    good = _write(tmp_path, stamps, rec.accel_mps2, name="good.mcap")
    bad_accel = rec.accel_mps2.copy()
    bad_accel[rec.samples // 2, 0] = 1e300
    bad = _write(tmp_path, stamps, bad_accel, name="bad.mcap")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        window_bad = api.calibrate(bad).window_s
    window_good = api.calibrate(good).window_s
    assert window_bad == pytest.approx(window_good, abs=0.05)


def _hostile_good_sessions():
    from wheelcal.simulate import hostile

    rng = np.random.default_rng(11)
    yield "clean", hostile.clean(rng).recording
    yield "10 samples per turn", hostile.sampled_at(rng, 40.0, omega_radps=25.0).recording
    yield "fast spin, 1 kHz", hostile.sampled_at(rng, 1000.0, omega_radps=25.0).recording
    yield "rising to 24.6 rad/s", hostile.rising(rng).recording
    yield "vibration 0.3", hostile.vibrating(rng, 0.3).recording
    yield "vibration 0.7", hostile.vibrating(rng, 0.7).recording
    yield "saturated ±2 g", hostile.saturated(rng).recording
    yield "saturated ±1.5 g, 3 LSB", hostile.saturated(rng, 1.5, 3.0).recording
    yield "motor steps", hostile.motor_steps(rng).recording


def test_good_data_has_no_gross_outliers():
    """Rails, centripetal swings at high ω, heavy vibration: nothing is flagged."""
    from wheelcal.recording.samples import InputPolicy, clean_samples

    for name, rec in _hostile_good_sessions():
        out = clean_samples(
            name,
            recording_stamps_ns(rec),
            rec.accel_mps2,
            unit="m/s^2",
            full_scale_g=None,
            policy=InputPolicy(max_clipped_fraction=0.5),  # outliers only, not clipping
        )
        assert not any("gross outlier" in n for n in out.notes), (name, out.notes)


# --- item 7: non-regular files, misleading messages, convert -------------------------------


def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path):
    fifo = tmp_path / "live.mcap"
    os.mkfifo(fifo)
    said = read_limited(fifo)  # a reader that waited for a writer would time out
    assert said.startswith("NotMcapError") and "live.mcap: is a FIFO" in said


def test_a_directory_is_refused(tmp_path):
    (tmp_path / "dir.mcap").mkdir()
    with pytest.raises(InputError, match=r"dir\.mcap: is a directory"):
        read_recording(tmp_path / "dir.mcap")


def _write_raw(
    path,
    schema_name,
    schema_encoding,
    schema_data,
    message_encoding,
    payloads,
    stamps,
    compression="zstd",
):
    from mcap.writer import CompressionType, Writer

    with open(path, "wb") as stream:
        kind = CompressionType[compression.upper()] if compression else CompressionType.NONE
        writer = Writer(stream, compression=kind)
        writer.start()
        sid = writer.register_schema(schema_name, schema_encoding, schema_data)
        cid = writer.register_channel("/imu", message_encoding, sid)
        for stamp, payload in zip(stamps.tolist(), payloads, strict=True):
            writer.add_message(cid, log_time=stamp, data=payload, publish_time=stamp)
        writer.add_metadata("wheelcal.session", {"radius_m": "0.28"})
        writer.finish()
    return path


def _json_file(tmp_path, base, damage, compression="zstd"):
    from wheelcal.io.accel_json import encode_accel_batches, schema_bytes

    stamps, accel = base
    payloads = [payload for _, payload in encode_accel_batches(stamps, accel, 1)]
    damage(payloads)
    return _write_raw(
        tmp_path / "msgs.mcap",
        "wheelcal.AccelBatch",
        "jsonschema",
        schema_bytes(),
        "json",
        payloads,
        stamps,
        compression,
    )


def test_invalid_utf8_names_the_message(tmp_path, base):
    def damage(payloads):
        payloads[1234] = payloads[1234].replace(b'"accel"', b'"acc\xffl"')

    with pytest.raises(
        InputError, match=r"msgs\.mcap: topic /imu: message 1234 is not valid UTF-8"
    ):
        read_recording(_json_file(tmp_path, base, damage))


@pytest.mark.parametrize("compression", ["zstd", ""])  # "": chunks read from the mapped file
def test_deeply_nested_json_is_a_corrupt_message(tmp_path, base, compression):
    def damage(payloads):
        payloads[4321] = b"[" * 200_000 + b"]" * 200_000

    with pytest.raises(InputError, match=r"msgs\.mcap: topic /imu: message 4321 is nested too"):
        read_recording(_json_file(tmp_path, base, damage, compression))


def test_imu_size_error_names_the_offending_message(tmp_path, base):
    from wheelcal.io.imu_cdr import IMU_MSGDEF, encode_imu_messages

    stamps, accel = base
    payloads = encode_imu_messages(stamps, accel, "imu")
    size = len(payloads[0])
    payloads[77] = payloads[77] + bytes(8)
    path = _write_raw(
        tmp_path / "imu.mcap",
        "sensor_msgs/msg/Imu",
        "ros2msg",
        IMU_MSGDEF.encode(),
        "cdr",
        payloads,
        stamps,
    )
    with pytest.raises(
        InputError, match=rf"message 77's size .* \({size + 8} bytes, expected {size}\)"
    ):
        read_recording(path)


def test_unit_hint_for_a_ros2_file_names_the_command_line_option(tmp_path, base):
    stamps, accel = base
    path = _write(tmp_path, stamps, accel / 9.80665, encoding="ros2")
    with pytest.raises(InputError, match=r"look like g") as caught:
        read_recording(path)
    message = str(caught.value)
    assert "--accel-unit g" in message and "REP 103" in message
    assert "metadata" not in message


def test_one_sample_a_second_is_refused_before_any_fit(tmp_path):
    n = 200
    stamps = 1_700_000_000_000_000_000 + 10**9 * np.arange(n, dtype=np.int64)
    angle = 2.0 * np.arange(n)
    accel = np.stack([7 * np.cos(angle), 7 * np.sin(angle), np.full(n, 6.5)], axis=1)
    with pytest.raises(InputError, match=r"1 s apart \(1 Hz\).*at least 10 samples per second"):
        read_recording(_write(tmp_path, stamps, accel))


def test_csv_field_over_128_kb_names_the_file_and_line(tmp_path):
    from wheelcal.io import convert_csv

    csv_path = tmp_path / "huge.csv"
    rows = ["# exported", "t,ax,ay,az", "0,1,2,9.8", "0.01,1," + "9" * 200_000 + ",9.8"]
    csv_path.write_text("\n".join(rows) + "\n")
    with pytest.raises(InputError, match=r"huge\.csv: line 4: cannot be read as CSV"):
        convert_csv(csv_path, tmp_path / "out.mcap")
    assert not (tmp_path / "out.mcap").exists()


def test_a_bad_optional_gyro_matters_only_when_the_gyro_is_read(tmp_path, base):
    """Decoding chunk by chunk must not make an unread optional field refuse a file."""
    import json

    def damage(payloads):
        message = json.loads(payloads[50])
        message["gyro"] = [[1.0, 2.0]]  # two numbers: not a gyro row
        payloads[50] = json.dumps(message).encode()

    path = _json_file(tmp_path, base, damage)
    assert read_recording(path, gyro=False, temperature=False).samples == base[0].size
    with pytest.raises(InputError, match=r'every "gyro" entry must be three numbers'):
        read_recording(path)


def _block_of(payloads):
    from wheelcal.io.mcap_scan import MessageBlock

    buffer = b"".join(payloads)
    lengths = np.array([len(p) for p in payloads], dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.int64)
    return MessageBlock(buffer, offsets, lengths, np.arange(len(payloads), dtype=np.int64))


def test_temperature_size_error_names_the_offending_message():
    from wheelcal.io.temperature_cdr import (
        TemperatureLayoutError,
        decode_temperature_blocks,
        encode_temperature_messages,
    )

    stamps = np.arange(20, dtype=np.int64) * 10_000_000
    payloads = encode_temperature_messages(stamps, np.full(20, 25.0), "imu")
    size = len(payloads[0])
    _, _, temps = decode_temperature_blocks((_block_of(payloads[:10]), _block_of(payloads[10:])))
    np.testing.assert_array_equal(temps, 25.0)
    payloads[13] = payloads[13] + bytes(8)
    with pytest.raises(
        TemperatureLayoutError, match=rf"message 13's size .* \({size + 8} bytes, expected {size}\)"
    ):
        decode_temperature_blocks((_block_of(payloads[:10]), _block_of(payloads[10:])))
