"""Bad input: every case is refused with an error naming the file and the problem,
or repaired with a note in Recording.notes — and no partial output is ever left.
"""

import os

import numpy as np
import pytest

from wheelcal.io import (
    CorruptFileError,
    InputError,
    MetadataError,
    NotMcapError,
    SampleError,
    TopicError,
    copy_with_channels,
    read_recording,
    require_radius,
    write_accel_mcap,
    write_recording,
)
from wheelcal.io.mcap_writer import ChannelData, accel_channel, recording_stamps_ns, write_channels

G = 9.80665


def write(tmp_path, stamps, accel, name="bad.mcap", **kwargs):
    kwargs.setdefault("session", {"radius_m": "0.28"})
    path = tmp_path / name
    write_accel_mcap(path, stamps, accel, **kwargs)
    return path


@pytest.fixture()
def good(tmp_path, base):
    return write(tmp_path, *base, name="good.mcap", compression="none")


# --- not an MCAP file / damaged files -------------------------------------------------


def test_not_mcap(tmp_path):
    # Text that is no table (a CSV is read: tests/test_csv_direct.py).
    path = tmp_path / "log.txt"
    path.write_text("spin of monday\nno samples here\n")
    with pytest.raises(NotMcapError, match=r"log\.txt: not an MCAP file.*looks like text"):
        read_recording(path)


def test_empty_and_missing(tmp_path):
    (tmp_path / "empty.mcap").write_bytes(b"")
    with pytest.raises(NotMcapError, match=r"empty\.mcap: the file is empty"):
        read_recording(tmp_path / "empty.mcap")
    with pytest.raises(NotMcapError, match=r"nothere\.mcap: no such file"):
        read_recording(tmp_path / "nothere.mcap")


@pytest.mark.parametrize("keep", [0.5, 0.999, 20])
def test_truncated(tmp_path, good, keep):
    data = good.read_bytes()
    cut = int(len(data) * keep) if keep < 1 else keep
    path = tmp_path / "cut.mcap"
    path.write_bytes(data[:cut])
    with pytest.raises(CorruptFileError, match=r"cut\.mcap: the file is truncated"):
        read_recording(path)


@pytest.mark.parametrize("compression", ["none", "zstd", "lz4"])
def test_corrupted_chunk(tmp_path, base, compression):
    path = write(tmp_path, *base, name="flip.mcap", compression=compression)
    data = bytearray(path.read_bytes())
    header_len = int.from_bytes(data[9:17], "little")
    first = 8 + 9 + header_len  # first record after the Header
    while data[first] != 0x06:
        first += 9 + int.from_bytes(data[first + 1 : first + 9], "little")
    data[first + 9 + 2000] ^= 0x10  # a bit inside the chunk's records
    path.write_bytes(bytes(data))
    with pytest.raises(CorruptFileError, match=r"flip\.mcap: chunk at byte \d+: .*damaged"):
        read_recording(path)


def test_damaged_data_section_outside_chunks(tmp_path, good):
    data = bytearray(good.read_bytes())
    at = data.index(b"radius_m")  # the metadata record, protected by the data-section CRC
    data[at] ^= 0x01
    path = tmp_path / "meta.mcap"
    path.write_bytes(bytes(data))
    with pytest.raises(CorruptFileError, match=r"meta\.mcap: data-section CRC mismatch"):
        read_recording(path)


# --- topics -------------------------------------------------------------------------------


def test_no_accelerometer_topic(tmp_path, base):
    stamps, _ = base
    other = ChannelData(
        "/temperature", "demo.Temp", "jsonschema", b"{}", "json", ((int(stamps[0]), b"{}"),)
    )
    path = tmp_path / "temp.mcap"
    write_channels(path, [other])
    with pytest.raises(
        TopicError, match=r"temp\.mcap: no accelerometer topic .*/temperature \[demo\.Temp"
    ):
        read_recording(path)


def test_several_candidates(tmp_path, base):
    stamps, accel = base
    path = tmp_path / "two.mcap"
    write_channels(
        path,
        [
            accel_channel(stamps, accel, topic="/imu_left"),
            accel_channel(stamps, accel, topic="/imu_right"),
        ],
    )
    with pytest.raises(TopicError, match=r"two\.mcap: several .*/imu_left.*/imu_right.*--topic"):
        read_recording(path)


def test_topic_of_another_type(tmp_path, base):
    stamps, accel = base
    other = ChannelData("/temp", "demo.Temp", "jsonschema", b"{}", "json", ((1, b"{}"),))
    path = tmp_path / "t.mcap"
    write_channels(path, [accel_channel(stamps, accel), other])
    with pytest.raises(TopicError, match=r"t\.mcap: topic '/temp' is not an accelerometer topic"):
        read_recording(path, topic="/temp")


# --- session facts --------------------------------------------------------------------------


def test_radius_missing_is_allowed_until_required(tmp_path, base):
    path = write(tmp_path, *base, name="norad.mcap", session={"sensor_id": "a"})
    rec = read_recording(path)
    assert rec.info.radius_m is None
    with pytest.raises(MetadataError, match=r"norad\.mcap: no wheel radius.*--radius"):
        require_radius(rec)
    assert require_radius(read_recording(path, info_overrides={"radius_m": 0.3})) == 0.3


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("-0.28", "must be a positive length"),
        ("0", "must be a positive length"),
        ("abc", "not a number"),
    ],
)
def test_bad_radius(tmp_path, base, value, message):
    path = write(tmp_path, *base, name="rad.mcap", session={"radius_m": value})
    with pytest.raises(MetadataError, match=rf"rad\.mcap: radius_m = .*{message}"):
        read_recording(path)


def test_bad_gravity(tmp_path, base):
    path = write(
        tmp_path, *base, name="grav.mcap", session={"radius_m": "0.28", "gravity_mps2": "1"}
    )
    with pytest.raises(
        MetadataError, match=r"grav\.mcap: .*gravity_mps2 = 1.0 is not a value of g"
    ):
        read_recording(path)


# --- samples: repaired ------------------------------------------------------------------------


def test_few_nans_are_dropped(tmp_path, base):
    stamps, accel = base
    accel = accel.copy()
    accel[[100, 2000, 3000], 1] = [np.nan, np.inf, -np.inf]
    rec = read_recording(write(tmp_path, stamps, accel))
    assert rec.samples == stamps.size - 3
    assert any("dropped 3 NaN/inf samples" in note for note in rec.notes)


def test_few_duplicates_are_merged(tmp_path, base):
    stamps0, accel0 = base
    stamps = np.insert(stamps0, [500, 900], stamps0[[500, 900]])
    accel = np.insert(accel0, [500, 900], accel0[[500, 900]], axis=0)
    accel[901] += 0.2  # the copy of sample 900 differs: the two are averaged
    rec = read_recording(write(tmp_path, stamps, accel, encoding="json"))
    np.testing.assert_array_equal(recording_stamps_ns(rec), stamps0)
    note = next(n for n in rec.notes if "repeated a timestamp" in n)
    assert "1 identical copies dropped" in note
    assert "1 stamps with differing values averaged" in note
    np.testing.assert_array_equal(rec.accel_mps2[500], accel0[500])
    np.testing.assert_allclose(rec.accel_mps2[900], accel0[900] + 0.1, rtol=1e-14)


def test_swapped_packets_are_sorted(tmp_path, base):
    stamps, accel = base
    order = np.arange(stamps.size)
    order[1000:1010], order[1010:1020] = order[1010:1020].copy(), order[1000:1010].copy()
    rec = read_recording(
        write(tmp_path, stamps[order], accel[order], encoding="json", batch_size=10)
    )
    np.testing.assert_array_equal(recording_stamps_ns(rec), stamps)
    np.testing.assert_array_equal(rec.accel_mps2, accel)
    assert any("sorted 1 out-of-order" in note for note in rec.notes)


def test_gaps_are_kept_and_reported(tmp_path, base):
    stamps, accel = base
    keep = np.ones(stamps.size, bool)
    keep[3000:3100] = False  # 0.5 s lost on the radio link
    rec = read_recording(write(tmp_path, stamps[keep], accel[keep]))
    np.testing.assert_array_equal(recording_stamps_ns(rec), stamps[keep])
    note = next(n for n in rec.notes if "gap" in n)
    assert "1 gap(s)" in note and "longest 0.505 s" in note


def test_clipping_at_the_stated_range_is_dropped(tmp_path, base):
    stamps, accel = base
    full_scale_g = round(float(np.quantile(np.abs(accel).max(axis=1), 0.97)) / G, 2)
    limit = full_scale_g * G
    clipped = np.clip(accel, -limit, limit)
    n_clip = int(np.any(np.abs(accel) >= 0.995 * limit, axis=1).sum())
    assert 0 < n_clip < 0.2 * stamps.size
    session = {"radius_m": "0.28", "full_scale_g": repr(full_scale_g)}
    rec = read_recording(write(tmp_path, stamps, clipped, session=session))
    assert rec.samples == stamps.size - n_clip
    assert any("clipped samples" in n and f"±{full_scale_g:g} g" in n for n in rec.notes)


def test_clipping_detected_as_runs_at_the_rail(tmp_path, base):
    stamps, accel = base
    axis = int(np.argmax(accel.max(axis=0)))
    rail = float(np.quantile(accel[:, axis], 0.97))
    clipped = accel.copy()
    clipped[:, axis] = np.minimum(accel[:, axis], rail)
    rec = read_recording(write(tmp_path, stamps, clipped))
    hit = int((accel[:, axis] >= rail).sum())
    assert rec.samples == stamps.size - hit
    assert any("runs at the extreme value" in n and "xyz"[axis] in n for n in rec.notes)
    # No false alarm on the unclipped data.
    assert not any("clipped" in n for n in read_recording(write(tmp_path, stamps, accel)).notes)


# --- samples: refused -------------------------------------------------------------------------


def _refused(tmp_path, stamps, accel, pattern, **kwargs):
    path = write(tmp_path, stamps, accel, name="refused.mcap", **kwargs)
    with pytest.raises(SampleError, match=r"refused\.mcap \(topic [^)]+\): " + pattern):
        read_recording(path)


def test_many_nans_refused(tmp_path, base):
    stamps, accel = base
    accel = accel.copy()
    accel[::20] = np.nan
    _refused(tmp_path, stamps, accel, r"\d+ of \d+ samples .* are NaN or infinite")


def test_packet_stamps_refused(tmp_path, base):
    stamps, accel = base
    packet = stamps[::10].repeat(10)[: stamps.size]  # one stamp per 10-sample packet
    _refused(tmp_path, packet, accel, r".*repeat the previous timestamp.*own time")


def test_chaotic_order_refused(tmp_path, base):
    stamps, accel = base
    order = np.random.default_rng(0).permutation(stamps.size)
    _refused(tmp_path, stamps[order], accel[order], r"timestamps go backwards \d+ times.*chaotic")


def test_clock_reset_refused(tmp_path, base):
    stamps, accel = base
    jumped = stamps.copy()
    jumped[4000:] -= 2_000_000_000  # the clock steps back 2 s
    _refused(tmp_path, jumped, accel, r"timestamps jump back by 1\.995 s.*clock reset")


def test_mostly_clipped_refused(tmp_path, base):
    stamps, accel = base
    session = {"radius_m": "0.28", "full_scale_g": "1"}
    _refused(
        tmp_path,
        stamps,
        np.clip(accel, -G, G),
        r".*are clipped at the sensor range",
        session=session,
    )


def test_g_labelled_as_mps2_refused(tmp_path, base):
    stamps, accel = base
    _refused(tmp_path, stamps, accel / G, r"at rest the samples read \|a\| = 1.*look like g")
    # ... and read correctly once the unit is stated.
    path = write(tmp_path, stamps, accel / G, name="ing.mcap", encoding="json")
    rec = read_recording(path, accel_unit="g")
    np.testing.assert_allclose(rec.accel_mps2, accel, rtol=1e-15, atol=1e-13)


def test_mps2_labelled_as_g_refused(tmp_path, base):
    stamps, accel = base
    _refused(
        tmp_path,
        stamps,
        accel,
        r".*look like m/s\^2, but the file says g",
        encoding="json",
        unit="g",
    )


def test_too_short_refused(tmp_path, base):
    stamps, accel = base
    _refused(tmp_path, stamps[:1000], accel[:1000], r"the recording is too short: 1000 usable")


# --- writers leave nothing partial ------------------------------------------------------------


def test_copy_of_a_damaged_file_writes_nothing(tmp_path, good):
    data = bytearray(good.read_bytes())
    data[len(data) // 2] ^= 0xFF
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    out = tmp_path / "copy.mcap"
    stamps = np.array([1_700_000_000_000_000_000])
    with pytest.raises(InputError, match=r"damaged\.mcap: "):
        copy_with_channels(damaged, out, [accel_channel(stamps, [[0, 0, G]], topic="/cal")])
    assert not out.exists()
    assert sorted(os.listdir(tmp_path)) == ["damaged.mcap", "good.mcap"]


def test_writer_refuses_before_creating_anything(tmp_path, base):
    from wheelcal.recording import Recording

    stamps, accel = base
    rec = Recording(
        time_s=(stamps - stamps[0]) * 1e-9, accel_mps2=accel, epoch_unix_ns=int(stamps[0])
    )
    with pytest.raises(ValueError, match="compression"):
        write_recording(rec, tmp_path / "x.mcap", compression="brotli")
    with pytest.raises(ValueError, match="encoding"):
        write_recording(rec, tmp_path / "x.mcap", encoding="protobuf")
    assert os.listdir(tmp_path) == []


def test_errors_survive_pickling():
    """Parallel batches send errors between processes."""
    import pickle

    error = pickle.loads(pickle.dumps(SampleError("/data/s1.mcap", "too short")))
    assert isinstance(error, SampleError)
    assert (str(error), error.path) == ("/data/s1.mcap: too short", "/data/s1.mcap")
