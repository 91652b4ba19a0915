"""Reading and writing the gyro and the temperature: formats, alignment through repairs, clipping.

Files are generated into tmp_path; the ROS 2 reference writer (mcap_ros2)
checks the CDR layouts independently of wheelcal's own encoder.
"""

import dataclasses
import json

import numpy as np
import pytest

from wheelcal.io import (
    InputError,
    MetadataError,
    SampleError,
    read_recording,
    write_accel_mcap,
    write_recording,
)
from wheelcal.io.accel_json import decode_accel_batch
from wheelcal.io.imu_cdr import IMU_MSGDEF
from wheelcal.io.mcap_scan import scan_mcap
from wheelcal.io.mcap_writer import (
    ChannelData,
    accel_channel,
    recording_stamps_ns,
    temperature_channel,
    write_channels,
)
from wheelcal.io.temperature_cdr import TEMPERATURE_MSGDEF
from wheelcal.recording import Recording, RecordingError, SessionInfo
from wheelcal.simulate import GyroSpec, Scenario, TemperatureSpec, simulate, table2

G = 9.80665
DPS = np.pi / 180


def _filled(gyro: np.ndarray) -> np.ndarray:
    """The fixture's missing gyro rows held at the reading before (zeros would be glitches)."""
    out = np.array(gyro, dtype=float)
    for hole in np.flatnonzero(np.isnan(out[:, 0])):
        out[hole] = out[hole - 1]
    return out


@pytest.fixture(scope="module")
def recording():
    """A 20 s Table II recording with a gyro (a few rows left out) and a temperature."""
    base = table2(rng=np.random.default_rng(3))
    scenario = Scenario(
        truth=base.truth,
        duration_s=20.0,
        info=SessionInfo(radius_m=0.28, gyro_full_scale_dps=2000.0),
        gyro=GyroSpec(),
        temperature=TemperatureSpec(),
    )
    rec = simulate(scenario, np.random.default_rng(4), epoch_unix_ns=1_712_345_678_901_234_567)
    gyro = np.array(rec.recording.gyro_radps)
    gyro[[10, 11, 500]] = np.nan
    return dataclasses.replace(rec.recording, gyro_radps=gyro)


@pytest.mark.parametrize(("encoding", "batch"), [("ros2", 1), ("json", 1), ("json", 7)])
def test_gyro_and_temperature_round_trip_exactly(recording, tmp_path, encoding, batch):
    path = tmp_path / "g.mcap"
    write_recording(recording, path, encoding=encoding, batch_size=batch)
    back = read_recording(path)
    np.testing.assert_array_equal(back.gyro_radps, recording.gyro_radps)  # NaN rows too
    np.testing.assert_array_equal(back.temperature_c, recording.temperature_c)
    np.testing.assert_array_equal(back.accel_mps2, recording.accel_mps2)
    assert back.info.gyro_full_scale_dps == 2000.0
    assert back.notes == (
        "gyro: 3 of 4001 samples (0.075 %) have no reading (absent from "
        "their message, or NaN/inf); left out",
    )
    # Reading the accelerometer only is the old reader, to the bit.
    plain = read_recording(path, gyro=False, temperature=False)
    assert plain.gyro_radps is None and plain.temperature_c is None and plain.notes == ()
    np.testing.assert_array_equal(plain.accel_mps2, back.accel_mps2)


def test_reference_ros2_writer_gyro_on_some_messages_and_a_slower_temperature_topic(
    recording, tmp_path
):
    """mcap_ros2 writes Imu (gyro absent on every 5th message) and a 10 Hz Temperature topic."""
    from mcap_ros2.writer import Writer

    path = tmp_path / "ref.mcap"
    stamps = recording_stamps_ns(recording)[:2400]
    rate = _filled(recording.gyro_radps[:2400]) + 0.5  # no exact zeros anywhere
    with open(path, "wb") as stream:
        writer = Writer(stream)
        imu = writer.register_msgdef("sensor_msgs/msg/Imu", IMU_MSGDEF)
        temp = writer.register_msgdef("sensor_msgs/msg/Temperature", TEMPERATURE_MSGDEF)
        for i, (stamp, a, w) in enumerate(
            zip(stamps.tolist(), recording.accel_mps2, rate, strict=False)
        ):
            sec, nsec = divmod(stamp, 1_000_000_000)
            absent = i % 5 == 0
            writer.write_message(
                "/imu/data_raw",
                imu,
                {
                    "header": {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": "imu_link_17"},
                    "linear_acceleration": {"x": a[0], "y": a[1], "z": a[2]},
                    "angular_velocity": {"x": w[0], "y": w[1], "z": w[2]},
                    "angular_velocity_covariance": [-1.0 if absent else 0.0] + [0.0] * 8,
                },
                log_time=stamp,
            )
        # Temperature: own stamps (10 Hz, offset 37 ms), a linear ramp 20 → 22 °C.
        first = int(stamps[0])
        for k in range(-2, 125):
            stamp = first + 37_000_000 + k * 100_000_000
            sec, nsec = divmod(stamp, 1_000_000_000)
            writer.write_message(
                "/imu/temperature",
                temp,
                {
                    "header": {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": "imu"},
                    "temperature": 20.0 + 2.0 * (stamp - first) / 12e9,
                },
                log_time=stamp,
            )
        writer.finish()
    back = read_recording(path, info_overrides={"radius_m": 0.28})
    absent = np.arange(2400) % 5 == 0
    assert np.all(np.isnan(back.gyro_radps[absent]))
    np.testing.assert_array_equal(back.gyro_radps[~absent], rate[~absent])
    expected = 20.0 + 2.0 * (stamps - first) / 12e9
    np.testing.assert_allclose(back.temperature_c, expected, atol=1e-12)
    assert any("480 of 2400 samples" in note for note in back.notes)


def _raw_file(path, stamps, accel, gyro, **kwargs):
    write_accel_mcap(path, stamps, accel, encoding="json", batch_size=9, gyro=gyro, **kwargs)


def test_reader_repairs_keep_gyro_rows_with_their_samples(recording, tmp_path):
    """Sorting, duplicate stamps, NaN and clipped accelerometer rows: each gyro row stays
    with its stamp (the gyro here *is* a function of the stamp, so any shift shows)."""
    stamps = recording_stamps_ns(recording).copy()
    accel = np.array(recording.accel_mps2)
    gyro = np.column_stack(
        [(stamps - stamps[0]) * 1e-9, np.full(stamps.size, 0.3), np.ones(stamps.size)]
    )
    # Out of order: swap a few neighbours.
    for i in (100, 2000, 3500):
        stamps[[i, i + 1]] = stamps[[i + 1, i]]
        accel[[i, i + 1]] = accel[[i + 1, i]]
        gyro[[i, i + 1]] = gyro[[i + 1, i]]
    # Duplicates: an identical copy, and a differing one.
    order = np.r_[np.arange(1200), 1199, np.arange(1200, 2600), 2599, np.arange(2600, stamps.size)]
    stamps, accel, gyro = stamps[order], accel[order], gyro[order]
    accel[2601] += 0.01  # second copy of stamp #2599 differs
    # NaN accelerometer rows and a clipped run (at ±full scale).
    accel[[50, 3000]] = np.nan
    full_scale_g = 4.0
    accel[700:705, 0] = full_scale_g * G
    path = tmp_path / "repaired.mcap"
    _raw_file(path, stamps, accel, gyro, session={"radius_m": "0.28", "full_scale_g": "4"})
    back = read_recording(path)
    assert len(back.notes) >= 4  # sorted, duplicates, NaN dropped, clipped dropped
    np.testing.assert_allclose(
        back.gyro_radps[:, 0],
        back.time_s + (back.epoch_unix_ns - recording.epoch_unix_ns) * 1e-9,
        atol=1e-12,
    )
    assert back.samples == recording.samples - 2 - 5
    assert np.all(back.gyro_radps[:, 1:] == [0.3, 1.0])


def test_gyro_clipped_at_the_stated_range_and_at_jittering_rails(tmp_path):
    """MPU-9250 at its power-on ±250 °/s (4.36 rad/s) on a spin slowing from 6.5 to 3.5 rad/s."""
    base = table2(rng=np.random.default_rng(8))
    spec = GyroSpec(full_scale_dps=250.0, bits=16)
    slowing = dataclasses.replace(base.truth.spin, omega_radps=(5.0, -0.15))
    scenario = Scenario(truth=base.truth.with_changes(spin=slowing), duration_s=20.0, gyro=spec)
    rec = simulate(scenario, np.random.default_rng(9)).recording
    lsb = spec.lsb_radps
    lo, hi = spec.limits_radps
    w = np.array(rec.gyro_radps)
    at_rail = np.any((w >= hi) | (w <= lo), axis=1)
    assert 0.2 < at_rail.mean() < 1.0
    # A real ADC's rail toggles by a count.
    toggle = np.random.default_rng(10).integers(0, 2, size=w.shape) * lsb
    w = np.where(w >= hi, w - toggle, w)
    w = np.where(w <= lo, w + toggle, w)
    jittered = dataclasses.replace(rec, gyro_radps=w)
    for stated in (250.0, None):
        info = dataclasses.replace(rec.info, gyro_full_scale_dps=stated)
        path = tmp_path / f"clip_{stated}.mcap"
        write_recording(dataclasses.replace(jittered, info=info), path, encoding="ros2")
        back = read_recording(path)
        left_out = ~back.gyro_valid
        assert back.samples == rec.samples  # the accelerometer keeps every sample
        assert np.all(left_out[at_rail])  # every clipped row is left out ...
        if stated:  # the accelerometer's rule: within 0.5 % of the stated range
            near = np.any(np.abs(w) >= 0.995 * 250 * DPS, axis=1)
        else:  # within the rail's jitter
            near = np.any((w >= hi - 2 * lsb) | (w <= lo + 2 * lsb), axis=1)
        assert not np.any(left_out & ~near)  # ... and nothing far from the rails
        (note,) = [n for n in back.notes if "clipped" in n]
        assert ("±250 °/s" in note) if stated else ("rails" in note and "z = " in note)
    # A quantised gyro that never clips is not flagged (rest, slow spin: no rail runs).
    calm = Scenario(
        truth=base.truth.with_changes(
            spin=dataclasses.replace(base.truth.spin, omega_radps=(1.5,))
        ),
        duration_s=15.0,
        gyro=spec,
    )
    calm_rec = simulate(calm, np.random.default_rng(11)).recording
    write_recording(calm_rec, tmp_path / "calm.mcap", encoding="json")
    assert read_recording(tmp_path / "calm.mcap").gyro_valid.all()


def test_gyro_units_zero_channels_and_partial_nan(recording, tmp_path):
    stamps = recording_stamps_ns(recording)
    accel = recording.accel_mps2
    gyro_dps = _filled(recording.gyro_radps) / DPS + 5.0
    session = {"radius_m": "0.28"}
    # deg/s stated: converted.
    _raw_file(tmp_path / "deg.mcap", stamps, accel, gyro_dps, gyro_unit="deg/s", session=session)
    back = read_recording(tmp_path / "deg.mcap")
    np.testing.assert_allclose(back.gyro_radps, gyro_dps * DPS, rtol=1e-15)
    assert "gyro converted from deg/s" in back.notes
    # deg/s data labelled rad/s: refused, naming the file and the likely unit; override reads it.
    _raw_file(tmp_path / "mislabel.mcap", stamps, accel, gyro_dps, session=session)
    with pytest.raises(SampleError, match=r"mislabel\.mcap.*look like deg/s.*gyro_unit"):
        read_recording(tmp_path / "mislabel.mcap")
    fixed = read_recording(tmp_path / "mislabel.mcap", gyro_unit="deg/s")
    np.testing.assert_allclose(fixed.gyro_radps, gyro_dps * DPS, rtol=1e-15)
    # Beyond a stated range: refused too.
    _raw_file(
        tmp_path / "range.mcap",
        stamps,
        accel,
        gyro_dps * DPS * 3,
        session={**session, "gyro_full_scale_dps": "250"},
    )
    with pytest.raises(SampleError, match=r"range\.mcap.*beyond its stated range.*±250"):
        read_recording(tmp_path / "range.mcap")
    # An unknown unit in the metadata.
    channel = accel_channel(stamps, accel, encoding="json", gyro=gyro_dps)
    channel = dataclasses.replace(channel, metadata={"unit": "m/s^2", "gyro_unit": "rpm"})
    write_channels(tmp_path / "rpm.mcap", [channel], {"wheelcal.session": session})
    with pytest.raises(InputError, match=r"rpm\.mcap.*gyro unit 'rpm'"):
        read_recording(tmp_path / "rpm.mcap")
    with pytest.raises(InputError, match=r"deg\.mcap: gyro unit 'rpm'"):
        read_recording(tmp_path / "deg.mcap", gyro_unit="rpm")
    # An accelerometer-only driver that publishes zeros: no gyro.
    for encoding in ("ros2", "json"):
        write_accel_mcap(
            tmp_path / "z.mcap",
            stamps,
            accel,
            encoding=encoding,
            gyro=np.zeros((stamps.size, 3)),
            session=session,
        )
        zero = read_recording(tmp_path / "z.mcap")
        assert zero.gyro_radps is None and any("exactly zero" in n for n in zero.notes)
    # NaN in some gyro values (json.loads path: NaN is not JSON Arrow takes): rows left out.
    nan_gyro = gyro_dps * DPS
    nan_gyro[[3, 4]] = np.nan
    nan_gyro[7, 1] = np.nan
    _raw_file(tmp_path / "nan.mcap", stamps, accel, nan_gyro, session=session)
    nan_back = read_recording(tmp_path / "nan.mcap")
    assert np.flatnonzero(~nan_back.gyro_valid).tolist() == [3, 4, 7]


def test_json_gyro_on_some_messages_both_decoders_agree(recording, tmp_path):
    stamps = recording_stamps_ns(recording)[:40]
    accel = recording.accel_mps2[:40]
    gyro = np.arange(120.0).reshape(40, 3) * 1e-3 + 0.01
    temp = np.linspace(20, 21, 40)
    messages = []
    for i in range(0, 40, 10):
        body = {"timestamps_ns": stamps[i : i + 10].tolist(), "accel": accel[i : i + 10].tolist()}
        if i != 10:
            body["gyro"] = gyro[i : i + 10].tolist()
            if i == 20:
                body["gyro"][3] = None
        if i == 0:
            body["temperature_c"] = temp[:10].tolist()
        messages.append(body)
    for indent in (None, 1):  # one line each (Arrow) / pretty-printed (json.loads)
        payloads = [
            (m["timestamps_ns"][-1], json.dumps(m, indent=indent).encode()) for m in messages
        ]
        base = accel_channel(stamps, accel, encoding="json")
        channel = dataclasses.replace(base, messages=tuple(payloads))
        write_channels(tmp_path / "some.mcap", [channel])
        scan = scan_mcap(tmp_path / "some.mcap")
        (blocks,) = scan.blocks.values()
        out = decode_accel_batch(blocks)
        expected = gyro.copy()
        expected[10:20] = np.nan
        expected[23] = np.nan
        np.testing.assert_array_equal(out.gyro, expected)
        np.testing.assert_array_equal(out.temperature_c[:10], temp[:10])
        assert np.all(np.isnan(out.temperature_c[10:]))
    # A gyro list that does not match the stamps is an error naming the file.
    messages[1]["gyro"] = gyro[:3].tolist()
    payloads = [(m["timestamps_ns"][-1], json.dumps(m).encode()) for m in messages]
    write_channels(
        tmp_path / "bad.mcap",
        [dataclasses.replace(base, messages=tuple(payloads))],
        {"wheelcal.session": {"radius_m": "0.28"}},
    )
    with pytest.raises(InputError, match=r"bad\.mcap.*timestamps_ns.*gyro"):
        read_recording(tmp_path / "bad.mcap")


def test_temperature_defects_are_noted_not_fatal(recording, tmp_path):
    stamps = recording_stamps_ns(recording)
    session = {"wheelcal.session": {"radius_m": "0.28"}}
    accel = accel_channel(stamps, recording.accel_mps2, encoding="ros2")

    def read_with(temps_ns, values, **kwargs):
        channel = temperature_channel(temps_ns, values, **kwargs)
        write_channels(tmp_path / "t.mcap", [accel, channel], session)
        return read_recording(tmp_path / "t.mcap")

    kelvin = read_with(stamps[::50], np.full(stamps[::50].size, 298.0))
    assert kelvin.temperature_c is None
    assert any("298 is not a sensor's temperature in °C (kelvin?)" in n for n in kelvin.notes)
    other_clock = read_with(stamps[::50] - 3_600_000_000_000, np.full(stamps[::50].size, 25.0))
    assert other_clock.temperature_c is None
    assert any("do not overlap the samples" in n for n in other_clock.notes)
    partial = read_with(
        stamps[: stamps.size // 2 : 50], np.full(stamps[: stamps.size // 2 : 50].size, 25.0)
    )
    assert np.all(partial.temperature_c == 25.0)
    assert any("held at the end values" in n for n in partial.notes)
    # Two temperature topics, none in the accelerometer's namespace: neither is guessed.
    second = temperature_channel(
        stamps[::50], np.full(stamps[::50].size, 30.0), topic="/board/temp"
    )
    first = temperature_channel(stamps[::50], np.full(stamps[::50].size, 25.0), topic="/cpu/temp")
    write_channels(tmp_path / "two.mcap", [accel, first, second], session)
    two = read_recording(tmp_path / "two.mcap")
    assert two.temperature_c is None and any("several temperature topics" in n for n in two.notes)
    assert np.all(
        read_recording(tmp_path / "two.mcap", temperature_topic="/board/temp").temperature_c == 30.0
    )
    with pytest.raises(InputError, match=r"two\.mcap.*no sensor_msgs/msg/Temperature topic '/x'"):
        read_recording(tmp_path / "two.mcap", temperature_topic="/x")


def test_recording_validates_and_windows_the_optional_channels():
    t = np.arange(10) * 0.01
    a = np.zeros((10, 3))
    w = np.ones((10, 3))
    w[4] = np.nan
    rec = Recording(t, a, gyro_radps=w, temperature_c=np.linspace(20, 21, 10), source="m")
    assert rec.has_gyro and rec.gyro_valid.tolist() == [True] * 4 + [False] + [True] * 5
    part = rec.window(0.03, 0.06)
    assert part.samples == 4 and part.gyro_valid.tolist() == [True, False, True, True]
    np.testing.assert_array_equal(part.temperature_c, rec.temperature_c[3:7])
    assert not Recording(t, a).has_gyro and not Recording(t, a).gyro_valid.any()
    partly = w.copy()
    partly[2, 1] = np.nan
    with pytest.raises(RecordingError, match="m: gyro_radps row 2 is partly NaN"):
        Recording(t, a, gyro_radps=partly, source="m")
    with pytest.raises(RecordingError, match="inf"):
        Recording(t, a, gyro_radps=np.full((10, 3), np.inf))
    with pytest.raises(RecordingError, match=r"\(N, 3\) = \(10, 3\)"):
        Recording(t, a, gyro_radps=np.ones((9, 3)))
    with pytest.raises(RecordingError, match="temperature_c holds NaN"):
        Recording(t, a, temperature_c=np.full(10, np.nan))
    with pytest.raises(RecordingError, match="gyro_full_scale_dps must be a positive"):
        SessionInfo(gyro_full_scale_dps=-250.0)


def test_gyro_full_scale_is_a_session_fact(recording, tmp_path):
    path = tmp_path / "fs.mcap"
    write_recording(recording, path)
    assert (
        read_recording(path, info_overrides={"gyro_full_scale_dps": 500}).info.gyro_full_scale_dps
        == 500.0
    )
    with pytest.raises(
        MetadataError, match=r"fs\.mcap: gyro_full_scale_dps = -1.0 must be positive"
    ):
        read_recording(path, info_overrides={"gyro_full_scale_dps": -1})


def test_bad_temperature_message_layout_is_an_error_naming_the_topic(recording, tmp_path):
    stamps = recording_stamps_ns(recording)
    broken = ChannelData(
        topic="/imu/temperature",
        schema_name="sensor_msgs/msg/Temperature",
        schema_encoding="ros2msg",
        schema_data=TEMPERATURE_MSGDEF.encode(),
        message_encoding="cdr",
        messages=((int(stamps[0]), b"\x00\x01\x00\x00" + b"\x00" * 12),),
    )
    accel = accel_channel(stamps, recording.accel_mps2)
    write_channels(
        tmp_path / "bt.mcap", [accel, broken], {"wheelcal.session": {"radius_m": "0.28"}}
    )
    with pytest.raises(InputError, match=r"bt\.mcap: topic /imu/temperature: .*too short"):
        read_recording(tmp_path / "bt.mcap")


def test_a_bad_temperature_message_in_a_later_chunk_is_named_by_its_place_in_the_topic(
    recording, tmp_path
):
    stamps = recording_stamps_ns(recording)
    temperature = temperature_channel(stamps, np.full(stamps.size, 25.0), stride=2)
    messages = list(temperature.messages)
    log_time, payload = messages[1500]
    messages[1500] = (log_time, payload + bytes(8))  # 8 bytes too many
    broken = dataclasses.replace(temperature, messages=tuple(messages))
    accel = accel_channel(stamps, recording.accel_mps2)
    path = tmp_path / "late.mcap"
    write_channels(path, [accel, broken], chunk_bytes=64 * 1024)
    assert scan_mcap(path).chunks > 5  # the message is far from its chunk's start
    with pytest.raises(InputError, match=r"temperature: message 1500's size .* \(44 bytes"):
        read_recording(path)
