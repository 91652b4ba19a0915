"""A recording is validated once, at construction (issue 27, item 3).

:meth:`Recording.from_samples` is the one way raw samples become a recording:
the readers and ``wheelcal.calibrate(recording)`` both take it, so the same raw
samples give the same recording — arrays, repairs and their notes — from a file
or from memory.  The constructor itself checks only the invariants, and names
the source when one fails.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import wheelcal
from wheelcal.io import SampleError, read_recording, write_accel_mcap
from wheelcal.recording import Recording, RecordingError, SessionInfo
from wheelcal.recording.temperature import TemperatureReadings
from wheelcal.simulate import hostile
from wheelcal.simulate.gyro import GyroSpec

G = 9.80665
EPOCH_NS = 1_700_000_000_123_456_789


@pytest.fixture(scope="module")
def session():
    return hostile.clean(np.random.default_rng(8), gyro=GyroSpec())


def _raw(recording: Recording):
    """The recording's samples as a logger writes them: out of order, repeated, NaN, a glitch."""
    stamps = EPOCH_NS + np.rint(recording.time_s * 1e9).astype(np.int64)
    accel = np.array(recording.accel_mps2)
    gyro = np.array(recording.gyro_radps)
    order = np.arange(stamps.size)
    order[1000:1010] = order[1000:1010][::-1]  # two writer threads
    stamps, accel, gyro = stamps[order], accel[order], gyro[order]
    stamps = np.insert(stamps, 500, stamps[500])  # a repeated stamp, a differing value
    accel = np.insert(accel, 500, accel[500] + 0.25, axis=0)
    gyro = np.insert(gyro, 500, gyro[500], axis=0)
    accel[[40, 4000]] = np.nan
    accel[7000, 1] += 120.0  # a gross outlier
    gyro[9000, 2] = 3.7e7  # a bit error in the gyro
    return stamps, accel, gyro


def _same(a: Recording, b: Recording) -> None:
    for name in ("time_s", "accel_mps2", "gyro_radps", "temperature_c"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.epoch_unix_ns == b.epoch_unix_ns
    assert a.notes == b.notes


def test_from_samples_is_the_readers_path_to_the_bit(session, tmp_path):
    stamps, accel, gyro = _raw(session.recording)
    temperature = 21.0 + 0.002 * np.arange(stamps.size)
    info = SessionInfo(radius_m=0.28)
    path = tmp_path / "raw.mcap"
    write_accel_mcap(
        path,
        stamps,
        accel / G,
        info=info,
        encoding="json",
        batch_size=7,
        unit="g",
        gyro=np.degrees(gyro),
        gyro_unit="deg/s",
        temperature_c=temperature,
    )
    read = read_recording(path)
    built = Recording.from_samples(
        source=str(path),
        time_ns=stamps,
        accel=accel / G,
        unit="g",
        info=info,
        gyro=np.degrees(gyro),
        gyro_unit="deg/s",
        temperature=TemperatureReadings("temperature_c of the batches", stamps, temperature),
        topic=read.topic,
    )
    _same(built, read)
    notes = " ".join(read.notes)
    for repair in (
        "converted from g",
        "gyro converted from deg/s",
        "dropped 2 NaN/inf",
        "sorted",
        "repeated a timestamp",
        "gross outlier",
        "a logger's glitch",
    ):
        assert repair in notes, repair
    assert read.samples == session.recording.samples - 3  # 2 NaN, 1 outlier; the copy merged


@pytest.mark.parametrize("unit", ["m/s^2", "g"])
def test_the_callers_arrays_are_left_as_they_are(session, unit):
    rec = session.recording
    stamps = EPOCH_NS + np.rint(rec.time_s * 1e9).astype(np.int64)
    accel = np.array(rec.accel_mps2) / (G if unit == "g" else 1.0)
    given = stamps.copy(), accel.copy()
    built = Recording.from_samples(source="m", time_ns=stamps, accel=accel, unit=unit)
    np.testing.assert_array_equal(stamps, given[0])
    np.testing.assert_array_equal(accel, given[1])
    assert stamps.flags.writeable and accel.flags.writeable
    assert not np.shares_memory(built.accel_mps2, accel)
    np.testing.assert_array_equal(built.accel_mps2, given[1] * (G if unit == "g" else 1.0))


def test_handed_over_columns_are_kept_without_a_copy(session):
    rec = session.recording
    stamps = EPOCH_NS + np.rint(rec.time_s * 1e9).astype(np.int64)
    accel = np.array(rec.accel_mps2) / G
    want_s, want_mps2 = (stamps - stamps[0]) * 1e-9, accel * G
    built = Recording.from_samples(source="m", time_ns=stamps, accel=accel, unit="g", consume=True)
    assert np.shares_memory(built.accel_mps2, accel)  # converted in place, kept
    assert np.shares_memory(built.time_s, stamps)  # seconds in the stamps' own memory
    np.testing.assert_array_equal(built.accel_mps2, want_mps2)
    np.testing.assert_array_equal(built.time_s, want_s)
    assert built.epoch_unix_ns == EPOCH_NS + int(np.rint(rec.time_s[0] * 1e9))


def test_a_recording_in_memory_gets_the_readers_repairs_and_notes(session):
    rec = session.recording
    accel = np.array(rec.accel_mps2)
    accel[7000, 1] += 120.0
    glitched = dataclasses.replace(rec, accel_mps2=accel, notes=("from the bench",))
    checked = glitched.checked()
    assert checked.samples == rec.samples - 1
    assert checked.notes[0] == "from the bench" and "gross outlier" in checked.notes[1]
    cal = wheelcal.calibrate(glitched, radius_m=0.28)
    assert tuple(cal.document["source"]["notes"][:2]) == checked.notes


def test_the_api_holds_a_stated_unit_to_the_data_as_the_reader_does(session):
    rec = session.recording
    # the unit was the keyword's, not the file's: the message says so (issue 39)
    with pytest.raises(SampleError, match="they look like m/s\\^2, but accel_unit='g' says g"):
        wheelcal.calibrate(rec, radius_m=0.28, accel_unit="g")
    in_g = dataclasses.replace(rec, accel_mps2=rec.accel_mps2 / G)
    checked = in_g.checked(unit="g")
    assert checked.notes == ("samples converted from g (9.80665 m/s²)",)
    np.testing.assert_allclose(checked.accel_mps2, rec.accel_mps2, rtol=1e-15)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"time_s": np.array([0.0, 0.1, 0.1, 0.3])}, "not strictly increasing"),
        ({"time_s": np.array([0.0, np.nan, 0.2, 0.3])}, "non-finite timestamps"),
        ({"time_s": np.array([0.0, 0.1, 0.2])}, r"need N times and \(N, 3\) samples"),
        ({"accel_mps2": np.full((4, 3), np.inf)}, "non-finite samples"),
        ({"accel_mps2": np.ones((4, 2))}, r"\(N, 3\) samples"),
        ({"accel_mps2": np.ones((4, 3), complex)}, "accel_mps2 must be real numbers"),
        ({"time_s": ["0", "a", "b", "c"]}, "time_s must be real numbers"),
        ({"clip_limits_mps2": np.ones(4)}, r"clip_limits_mps2 must be \(3, 2\)"),
        ({"temperature_c": np.ones(3)}, "temperature_c needs one value per sample"),
        ({"info": {"radius_m": 0.28}}, "info must be a SessionInfo"),
    ],
)
def test_the_invariants_name_the_source(change, message):
    fields = {"time_s": np.arange(4) * 0.1, "accel_mps2": np.ones((4, 3)), "source": "bench.mcap"}
    with pytest.raises(RecordingError, match=r"^bench\.mcap: .*" + message):
        Recording(**(fields | change))


def test_a_unit_no_source_states_is_refused_by_name():
    with pytest.raises(RecordingError, match="m: unit 'mg' is not one of"):
        Recording.from_samples(source="m", time_ns=np.arange(4), accel=np.ones((4, 3)), unit="mg")
    with pytest.raises(RecordingError, match="m: gyro unit 'rpm' is not one of"):
        Recording.from_samples(
            source="m",
            time_ns=np.arange(4),
            accel=np.ones((4, 3)),
            gyro=np.ones((4, 3)),
            gyro_unit="rpm",
        )
