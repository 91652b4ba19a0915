"""CSV exports read directly by ``calibrate``, ``batch`` and the API (CONTRACT: "calibrate
and apply also read the CSV exports of common IMU loggers whose format states the units").

Every CSV is written here, from a simulated session, in the exact layout its exporter
writes: the Xsens (Movella) DOT export (``sep=,``, ``", "`` between values, a trailing
comma, the first row all zeros, a 32-bit µs clock that wraps, a 16-bit packet counter,
glitches), the Movella DOT app's preamble and other payloads, x-io's NGIMU
``sensors.csv`` and x-IMU3 ``Inertial.csv``, and an Arduino log that states no unit.
A real Xsens DOT file is read when ``../shared/real`` is there (else skipped).
"""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

import wheelcal
from wheelcal.cli.main import main
from wheelcal.io import InputError, read_recording
from wheelcal.io.mcap_writer import recording_stamps_ns
from wheelcal.simulate import GyroSpec, TemperatureSpec, simulate_session, table2

G = 9.80665
XSENS_HEADER = (
    "PacketCounter,SampleTimeFine,Euler_X,Euler_Y,Euler_Z,Acc_X,Acc_Y,Acc_Z,Gyr_X,Gyr_Y,Gyr_Z,"
)
REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "real"


@pytest.fixture(scope="module")
def session():
    rng = np.random.default_rng(31)
    scenario = dataclasses.replace(
        table2(rng=rng), duration_s=20.0, gyro=GyroSpec(), temperature=TemperatureSpec()
    )
    return simulate_session(scenario, rng).recording


def _micros(rec) -> np.ndarray:
    return np.rint(rec.time_s * 1e6).astype(np.int64)


def _xsens(path, rec, *, start_us=2**32 - 5_000_000, lost=(), nan_row=None, spike_row=None):
    """The DOT export as the WID car data has it: ``sep=,``, ``, `` separators, trailing comma.

    A first row of zeros (Acc, Gyr) a step before the samples; rows ``lost`` left out (the
    packet counter skips them); ``nan_row`` written NaN/Infinity; ``spike_row`` +80 m/s².
    """
    rel_us = _micros(rec)
    accel = rec.accel_mps2.copy()
    gyro_dps = np.degrees(rec.gyro_radps)
    if spike_row is not None:
        accel[spike_row, 0] += 80.0
    lines = ["sep=,", XSENS_HEADER]
    euler = "-84.259033203125, -42.10929870605469, -47.84157943725586"
    lines.append(f"65000, {(start_us - 8333) % 2**32}, {euler}, 0, 0, 0, 0, 0, 0, ")
    for i in range(rec.samples):
        if i in lost:
            continue
        a = ", ".join(repr(float(v)) for v in accel[i])
        w = ", ".join(repr(float(v)) for v in gyro_dps[i])
        if i == nan_row:
            a, w = "NaN, NaN, NaN", "Infinity, -Infinity, -Infinity"
        counter = (65_000 + i + 1) % 65536  # 16-bit: wraps 535 rows in
        lines.append(f"{counter}, {(start_us + rel_us[i]) % 2**32}, {euler}, {a}, {w}, ")
    path.write_text("\n".join(lines) + "\n")
    return path


def _rows_of(rec, back, start_us=2**32 - 5_000_000) -> np.ndarray:
    """The indices into ``rec`` of the samples ``back`` kept (matched by their µs stamps)."""
    rel_us = recording_stamps_ns(back) // 1000 - start_us  # the clock unwrapped: absolute
    index = np.searchsorted(_micros(rec), rel_us)
    np.testing.assert_array_equal(_micros(rec)[index], rel_us)
    return index


def test_xsens_dot_export_is_read_with_the_units_its_format_fixes(session, tmp_path):
    # two packets lost where the 16-bit counter wraps (65534 → 1), a NaN row
    csv = _xsens(tmp_path / "IMU1_radial.csv", session, lost=(534, 535), nan_row=900)
    back = read_recording(csv)
    assert back.rate_hz == pytest.approx(200.0, rel=1e-3)
    kept = _rows_of(session, back)
    assert kept.size == session.samples - 3
    assert 534 not in kept and 535 not in kept and 900 not in kept
    np.testing.assert_array_equal(back.accel_mps2, session.accel_mps2[kept])  # m/s², exact
    np.testing.assert_allclose(back.gyro_radps, session.gyro_radps[kept], rtol=1e-13)  # deg/s
    # the 32-bit µs clock wrapped 5 s in: unwrapped, the times are the session's exactly
    np.testing.assert_array_equal(
        np.rint(back.time_s * 1e6).astype(np.int64), _micros(session)[kept] - _micros(session)[0]
    )
    notes = "\n".join(back.notes)
    assert "Xsens DOT CSV export" in notes and "Acc_* in m/s², Gyr_* in deg/s" in notes
    assert "SampleTimeFine in µs" in notes and "unwrapped 1 wrap(s)" in notes
    assert "dropped the first 1 samples: every axis reads exactly 0" in notes
    assert "dropped 1 NaN/inf samples" in notes
    assert "PacketCounter: 2 packet(s) missing in 1 place(s)" in notes  # across its 16-bit wrap
    assert back.topic == "" and back.info.radius_m is None


def test_a_direct_read_equals_convert_then_read(session, tmp_path):
    csv = _xsens(tmp_path / "dot.csv", session, spike_row=1200, nan_row=40)
    direct = read_recording(csv)
    assert main(["convert", str(csv), str(tmp_path / "dot.mcap")]) == 0  # no unit options
    converted = read_recording(tmp_path / "dot.mcap")
    assert direct.epoch_unix_ns == converted.epoch_unix_ns
    np.testing.assert_array_equal(direct.time_s, converted.time_s)
    np.testing.assert_array_equal(direct.accel_mps2, converted.accel_mps2)
    np.testing.assert_array_equal(direct.gyro_radps, converted.gyro_radps)
    assert any("gross outlier" in n for n in direct.notes)  # the spike, dropped by both
    # … so the calibration is the same number for number, by the API and the command line
    cal = wheelcal.calibrate(csv, radius_m=0.28)
    other = wheelcal.calibrate(tmp_path / "dot.mcap", radius_m=0.28)
    assert cal["parameters"] == other["parameters"]
    assert abs(cal.gain - 1.0).max() < 0.1
    out = tmp_path / "out"
    assert main(["calibrate", str(csv), "--radius", "0.28", "--out", str(out), "--quiet"]) == 0
    document = json.loads((out / "dot.calibration.json").read_text())
    assert document["parameters"] == cal["parameters"]
    assert any("Xsens DOT CSV export" in n for n in document["source"]["notes"])


def test_a_long_log_reads_and_converts_whole(tmp_path):
    """60,000 rows: several 1 MiB blocks of the reader, several pieces of the MCAP writer."""
    n = 60_000
    t = np.arange(n) / 200.0
    accel_g = np.stack([0.5 * np.cos(12 * t), 0.5 * np.sin(12 * t), 0.866 + 0 * t], axis=1)
    accel_g += np.random.default_rng(5).normal(0.0, 0.002, accel_g.shape)
    axes = [f"Accelerometer {a} (g)" for a in "XYZ"]
    csv = _table(tmp_path / "long.csv", ["Time (s)", *axes], [t.tolist(), *accel_g.T.tolist()])
    assert csv.stat().st_size > 2 << 20
    direct = read_recording(csv)
    assert direct.samples == n
    np.testing.assert_allclose(direct.accel_mps2, accel_g * G, rtol=1e-15)
    for fmt in ("json", "ros2"):
        out = tmp_path / f"long-{fmt}.mcap"
        assert main(["convert", str(csv), str(out), "--format", fmt]) == 0
        back = read_recording(out)
        np.testing.assert_array_equal(back.time_s, direct.time_s)
        np.testing.assert_allclose(back.accel_mps2, direct.accel_mps2, rtol=1e-15)


def test_a_batch_takes_csv_globs(session, tmp_path):
    folder = tmp_path / "logs"
    folder.mkdir()
    _xsens(folder / "a.csv", session)
    pipeline = tmp_path / "p.toml"
    pipeline.write_text(
        f'[pipeline]\nname = "csv"\noutput = "{tmp_path / "out"}"\n'
        f'[inputs]\nglobs = ["{folder}/*.csv"]\n[defaults]\nradius_m = 0.28\n'
        "[executor]\nworkers = 1\n"
    )
    assert main(["batch", str(pipeline)]) == 0
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["sessions"] == 1 and report["calibrated"] == 1
    assert (tmp_path / "out" / "a.calibration.json").exists()


def _movella_app(path, rec, header, columns, *, trailing=False):
    """The Movella DOT app's CSV: ``sep=,``, its preamble, a blank line, then the header."""
    pad = "," * 17
    preamble = [
        "sep=,",
        f"DeviceTag:,wheel-front{pad}",
        f"FirmwareVersion:,2.6.0{pad}",
        f"AppVersion:,2023.6.0{pad}",
        f"SyncStatus:,Un-synced{pad}",
        f"OutputRate:,120Hz{pad}",
        f"FilterProfile:,General{pad}",
        f"Measurement Mode:,Custom mode 5{pad}",
        f"StartTime:,2024-05-02 10:11:12.013 +0200{pad}",
        f"Movella Technologies B. V. 2005-2024,,{pad}",
        "",
        header + ("," if trailing else ""),
    ]
    end = ", " if trailing else ""
    rows = [", ".join(str(v) for v in row) + end for row in zip(*columns, strict=True)]
    path.write_text("\n".join(preamble + rows) + "\n")
    return path


def test_movella_app_payloads_with_acceleration_are_read_and_the_others_refused(session, tmp_path):
    rel_us = _micros(session)
    n = session.samples
    ones = [1.0] * n
    quat = [ones, [0.0] * n, [0.0] * n, [0.0] * n]
    accel = session.accel_mps2.T.tolist()
    gyro = np.degrees(session.gyro_radps).T.tolist()
    base = [list(range(n)), (1_000_000 + rel_us).tolist()]
    # "Custom mode 5": orientation, acceleration and angular velocity
    header = "PacketCounter,SampleTimeFine,Quat_W,Quat_X,Quat_Y,Quat_Z"
    header += ",Acc_X,Acc_Y,Acc_Z,Gyr_X,Gyr_Y,Gyr_Z"
    csv = _movella_app(tmp_path / "mode5.csv", session, header, base + quat + accel + gyro)
    back = read_recording(csv)
    np.testing.assert_array_equal(back.accel_mps2, session.accel_mps2)
    np.testing.assert_allclose(back.gyro_radps, session.gyro_radps, rtol=1e-13)
    assert any("skipped the exporter's 9 preamble lines" in n for n in back.notes)
    # Payloads without the accelerometer's readings are refused by name.
    for name, columns, said in [
        ("orientation", "Quat_W,Quat_X,Quat_Y,Quat_Z", "orientation (Quat_*/Euler_*)"),
        ("free", "Euler_X,Euler_Y,Euler_Z,FreeAcc_X,FreeAcc_Y,FreeAcc_Z", "free acceleration"),
        ("delta", "dq_W,dq_X,dq_Y,dq_Z,dv[1],dv[2],dv[3],Status", "delta quantities"),
        ("gyro", "Quat_W,Quat_X,Quat_Y,Quat_Z,Gyr_X,Gyr_Y,Gyr_Z", "angular velocity (Gyr_*)"),
    ]:
        width = columns.count(",") + 1
        path = _movella_app(
            tmp_path / f"{name}.csv",
            session,
            f"PacketCounter,SampleTimeFine,{columns}",
            base + [ones] * width,
        )
        with pytest.raises(InputError, match=rf"{name}\.csv: an Xsens DOT CSV export without"):
            read_recording(path)
        with pytest.raises(InputError) as caught:
            read_recording(path)
        assert said in str(caught.value) and "Acc_X, Acc_Y, Acc_Z" in str(caught.value)
        assert main(["convert", str(path), str(tmp_path / f"{name}.mcap")]) == 1
        assert not (tmp_path / f"{name}.mcap").exists()


def _table(path, header, columns, fmt=repr):
    rows = [",".join(fmt(v) for v in row) for row in zip(*columns, strict=True)]
    path.write_text(",".join(header) + "\n" + "\n".join(rows) + "\n")
    return path


def test_x_io_exports_state_their_units_in_the_header(session, tmp_path):
    accel_g = (session.accel_mps2 / G).T.tolist()
    gyro_dps = np.degrees(session.gyro_radps).T.tolist()
    axes = [
        f"{s} {a} ({u})" for s, u in (("Gyroscope", "deg/s"), ("Accelerometer", "g")) for a in "XYZ"
    ]
    # NGIMU sensors.csv: seconds, then gyro, accelerometer, magnetometer, barometer
    mag = [[20.0] * session.samples] * 3
    ngimu = _table(
        tmp_path / "sensors.csv",
        [
            "Time (s)",
            *axes,
            "Magnetometer X (uT)",
            "Magnetometer Y (uT)",
            "Magnetometer Z (uT)",
            "Barometer (hPa)",
        ],
        [session.time_s.tolist(), *gyro_dps, *accel_g, *mag, [1013.25] * session.samples],
        fmt=lambda v: f"{v:.6f}",
    )
    back = read_recording(ngimu)
    np.testing.assert_allclose(back.accel_mps2, session.accel_mps2, atol=1e-6 * G)
    np.testing.assert_allclose(back.gyro_radps, session.gyro_radps, atol=np.radians(1e-6))
    assert "acceleration unit g from the header" in back.notes
    assert "gyro unit deg/s from the header" in back.notes
    # x-IMU3 Inertial.csv: integer microseconds
    imu3 = _table(
        tmp_path / "Inertial.csv",
        ["Timestamp (us)", *axes],
        [_micros(session).tolist(), *gyro_dps, *accel_g],
    )
    back = read_recording(imu3)
    np.testing.assert_allclose(back.accel_mps2, session.accel_mps2, rtol=1e-15)
    np.testing.assert_array_equal(np.rint(back.time_s * 1e6), _micros(session))
    # Bare X (g), Y (g), Z (g) may be linear or earth acceleration (NGIMU's linear.csv):
    linear = _table(
        tmp_path / "linear.csv",
        ["Time (s)", "X (g)", "Y (g)", "Z (g)"],
        [session.time_s.tolist(), *accel_g],
    )
    with pytest.raises(
        InputError, match=r"linear\.csv: columns \['X \(g\)'.*not named as an accel"
    ):
        read_recording(linear)


def test_a_log_that_states_no_unit_is_refused_with_the_convert_command(session, tmp_path, capsys):
    raw = np.round(session.accel_mps2 / G * 4096).astype(int)
    millis = np.round(session.time_s * 1e3).astype(int)
    rows = [f"{t},{x},{y},{z}" for t, (x, y, z) in zip(millis, raw.tolist(), strict=True)]
    csv = tmp_path / "arduino.csv"
    csv.write_text("millis,ax,ay,az\r\n" + "\r\n".join(rows) + "\r\n")
    assert main(["calibrate", str(csv), "--radius", "0.28", "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err
    assert str(csv) in err and "states no acceleration unit (columns ['ax', 'ay', 'az'])" in err
    assert f"wheelcal convert {csv} arduino.mcap --accel-unit m/s^2|g|mg|counts" in err
    assert not list((tmp_path / "o").glob("*.json"))
    # A time without a unit too: both are named, and convert's inference offered.
    csv.write_text("t,ax,ay,az\n" + "\n".join(f"{t / 1e3},1,2,9" for t in millis) + "\n")
    with pytest.raises(InputError, match=r"no time unit \(column 't'\) and no acceleration unit"):
        read_recording(csv)
    # A unit the file does not state may be given (the samples checked against it).
    floats = [
        f"{t},{x!r},{y!r},{z!r}"
        for t, (x, y, z) in zip(millis, session.accel_mps2.tolist(), strict=True)
    ]
    csv.write_text("millis,ax,ay,az\n" + "\n".join(floats) + "\n")
    back = read_recording(csv, accel_unit="m/s^2")
    np.testing.assert_array_equal(back.accel_mps2, session.accel_mps2)
    with pytest.raises(InputError, match=r"arduino\.csv: .*look like m/s\^2.*--accel-unit m/s\^2"):
        read_recording(csv, accel_unit="g")


def test_the_real_xsens_dot_files_read_as_converted(tmp_path):
    files = sorted(REAL.glob("wid-car/*/IMU*_radial.csv"))
    if not files:
        pytest.skip("../shared/real is absent (a clone of the project has no real data)")
    for path in files:
        direct = read_recording(path)
        assert direct.rate_hz == pytest.approx(120.0, abs=0.1), path
        at_rest = np.median(np.linalg.norm(direct.accel_mps2[:240], axis=1))  # the first 2 s
        assert 9.3 < at_rest < 10.3, path  # m/s²
        turning = np.nanmax(np.linalg.norm(direct.gyro_radps, axis=1))
        assert 5.0 < turning < 70.0, path  # rad/s (in deg/s it would read 57× more)
        mcap = tmp_path / f"{path.parent.name}_{path.stem}.mcap"
        assert main(["convert", str(path), str(mcap)]) == 0
        converted = read_recording(mcap)
        np.testing.assert_array_equal(direct.time_s, converted.time_s)
        np.testing.assert_array_equal(direct.accel_mps2, converted.accel_mps2)
        np.testing.assert_array_equal(direct.gyro_radps, converted.gyro_radps)
        assert direct.epoch_unix_ns == converted.epoch_unix_ns
