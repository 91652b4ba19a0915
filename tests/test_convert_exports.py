"""``wheelcal convert`` on CSV files as real exporters write them (issue 14 item 5, issue 13).

Each CSV is written from a simulated session with rests (so the unit check
has a quiet stretch), a gyro and a temperature; the converted MCAP is read
back and compared number for number with what was written.
"""

import dataclasses

import numpy as np
import pytest

from wheelcal.cli.main import main
from wheelcal.io import InputError, read_recording
from wheelcal.io.csv_convert import CsvLayout, convert_csv
from wheelcal.io.mcap_writer import recording_stamps_ns
from wheelcal.simulate import GyroSpec, TemperatureSpec, simulate_session, table2

G = 9.80665


@pytest.fixture(scope="module")
def session():
    rng = np.random.default_rng(21)
    scenario = dataclasses.replace(
        table2(rng=rng), duration_s=20.0, gyro=GyroSpec(), temperature=TemperatureSpec()
    )
    return simulate_session(scenario, rng).recording


def _write_csv(path, header, columns, *, sep_line=None, trailing=False, delimiter=","):
    lines = [f"sep={sep_line}"] if sep_line else []
    end = delimiter if trailing else ""
    lines.append(delimiter.join(header) + end)
    for row in zip(*columns, strict=True):
        lines.append(delimiter.join(str(v) for v in row) + end)
    path.write_text("\n".join(lines) + "\n")


def _micros(rec, start_us):
    rel_us = np.rint(rec.time_s * 1e6).astype(np.int64)
    return (start_us + rel_us) % 2**32, rel_us


def test_xsens_style_export_converts_with_the_units_only(session, tmp_path):
    """`sep=,`, a trailing comma on every line, SampleTimeFine in µs, Acc_X/Acc_Y/Acc_Z."""
    ticks, rel_us = _micros(session, 81_234_567)
    accel = session.accel_mps2
    csv = tmp_path / "xsens.csv"
    _write_csv(
        csv,
        ["PacketCounter", "SampleTimeFine", "Acc_X", "Acc_Y", "Acc_Z"],
        [np.arange(ticks.size) % 65536, ticks, *accel.T.tolist()],
        sep_line=",",
        trailing=True,
    )
    out = tmp_path / "xsens.mcap"
    assert main(["convert", str(csv), str(out), "--accel-unit", "m/s^2", "--radius", "0.28"]) == 0
    back = read_recording(out)
    np.testing.assert_array_equal(back.accel_mps2, accel)  # repr floats: exact
    np.testing.assert_array_equal(recording_stamps_ns(back) - back.epoch_unix_ns, rel_us * 1000)
    assert back.epoch_unix_ns == 81_234_567_000
    result = convert_csv(csv, tmp_path / "again.mcap", CsvLayout(accel_unit="m/s^2"))
    assert result.time_unit == "us" and result.rate_hz == pytest.approx(200.0)
    assert result.columns["time"] == "SampleTimeFine"
    assert result.columns["accel"] == ["Acc_X", "Acc_Y", "Acc_Z"]
    assert any("sep=," in n for n in result.notes)
    assert any("trailing column" in n for n in result.notes)
    # And it calibrates.
    assert main(["calibrate", str(out), "--out", str(tmp_path), "--quiet"]) == 0


def test_wrapping_32_bit_microsecond_counter_is_unwrapped(session, tmp_path):
    start = 2**32 - 7_000_000  # wraps 7 s in
    ticks, rel_us = _micros(session, start)
    assert np.any(np.diff(ticks) < 0)
    csv = tmp_path / "wrap.csv"
    _write_csv(csv, ["SampleTimeFine", "ax", "ay", "az"], [ticks, *session.accel_mps2.T.tolist()])
    result = convert_csv(csv, tmp_path / "wrap.mcap", CsvLayout(accel_unit="m/s^2"))
    assert any(
        "unwrapped 1 wrap(s) of the 32-bit counter 'SampleTimeFine'" in n for n in result.notes
    )
    back = read_recording(tmp_path / "wrap.mcap", info_overrides={"radius_m": 0.28})
    assert back.notes == ()  # no clock jump left for the reader to refuse
    np.testing.assert_array_equal(recording_stamps_ns(back) - back.epoch_unix_ns, rel_us * 1000)


@pytest.mark.parametrize(
    ("header", "scale", "decimals", "expected"),
    [
        ("t", 1.0, 6, "s"),  # 0.005 s steps: 200 Hz (ms would be 200 kHz)
        ("time", 1e9, 0, "ns"),  # 5e6 steps: only ns gives a plausible rate
        ("timestamp", 1e3, 3, "ms"),  # 5 ms steps: 200 Hz in ms, 0.2 Hz in s
        ("Time (s)", 1.0, 6, "s"),  # the bracketed unit
        ("time_ms", 1e3, 3, "ms"),
    ],
)
def test_time_unit_is_inferred(session, tmp_path, header, scale, decimals, expected):
    times = [f"{t * scale:.{decimals}f}" for t in session.time_s]
    csv = tmp_path / "t.csv"
    _write_csv(csv, [header, "ACC_X", "acc_y", "Acc_Z"], [times, *session.accel_mps2.T.tolist()])
    result = convert_csv(csv, tmp_path / "t.mcap", CsvLayout(accel_unit="m/s^2"))
    assert result.time_unit == expected and result.rate_hz == pytest.approx(200.0)
    back = read_recording(tmp_path / "t.mcap", info_overrides={"radius_m": 0.28})
    np.testing.assert_allclose(back.time_s, session.time_s, atol=1e-9)


def test_implausible_time_units_are_refused_and_ties_broken(session, tmp_path):
    ms = [f"{t * 1e3:.3f}" for t in session.time_s]
    csv = tmp_path / "ms.csv"
    _write_csv(csv, ["t", "ax", "ay", "az"], [ms, *session.accel_mps2.T.tolist()])
    out = tmp_path / "out.mcap"
    with pytest.raises(
        InputError,
        match=r"ms\.csv: the time column 't' in s \(as given\) implies a sampling rate of 0\.2 Hz, "
        r"not plausible .* wrong time unit; with --time-unit ms: 200 Hz",
    ):
        convert_csv(csv, out, CsvLayout(time_unit="s", accel_unit="m/s^2"))
    # Steps of 0.5: 2 Hz in s or 2 kHz in ms — the typical IMU rate wins ...
    rows = np.tile([[0.0, 0.0, G]], (300, 1)).T.tolist()
    half = [f"{0.5 * i:.1f}" for i in range(300)]
    _write_csv(tmp_path / "half.csv", ["time", "ax", "ay", "az"], [half, *rows])
    result = convert_csv(tmp_path / "half.csv", out, CsvLayout(accel_unit="m/s^2"))
    assert result.time_unit == "ms" and result.rate_hz == pytest.approx(2000.0)
    # ... unless the values are a Unix time in one unit only (1.7e9 s; as ms it is 1970).
    epoch = [f"{1_712_345_678 + 0.5 * i:.1f}" for i in range(300)]
    _write_csv(tmp_path / "epoch.csv", ["time", "ax", "ay", "az"], [epoch, *rows])
    result = convert_csv(tmp_path / "epoch.csv", out, CsvLayout(accel_unit="m/s^2"), replace=True)
    assert result.time_unit == "s" and result.rate_hz == pytest.approx(2.0)
    # Counters that advance by ~1e7 per sample with a name saying µs: 0.1 Hz, refused.
    ticks = [str(10_000_000 * i) for i in range(300)]
    _write_csv(tmp_path / "fine.csv", ["SampleTimeFine", "ax", "ay", "az"], [ticks, *rows])
    with pytest.raises(InputError, match=r"fine\.csv: .*in us \(as its name says\).*0\.1 Hz"):
        convert_csv(tmp_path / "fine.csv", tmp_path / "fine.mcap", CsvLayout(accel_unit="m/s^2"))
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "epoch.csv",
        "fine.csv",
        "half.csv",
        "ms.csv",
        "out.mcap",
    ]


def test_stated_acceleration_unit_is_checked_against_gravity(session, tmp_path):
    in_g = (session.accel_mps2 / G).T.tolist()
    csv = tmp_path / "g.csv"
    _write_csv(csv, ["t", "ax", "ay", "az"], [session.time_s.tolist(), *in_g])
    with pytest.raises(
        InputError,
        match=r"g\.csv: at rest the samples read \|a\| = 1\.0.*look like g \(--accel-unit g\)",
    ):
        convert_csv(csv, tmp_path / "g.mcap", CsvLayout(accel_unit="m/s^2"))
    assert main(["convert", str(csv), str(tmp_path / "g.mcap"), "--accel-unit", "m/s^2"]) == 1
    assert not (tmp_path / "g.mcap").exists()
    in_mg = (session.accel_mps2 / G * 1000).T.tolist()
    _write_csv(csv, ["t", "ax", "ay", "az"], [session.time_s.tolist(), *in_mg])
    with pytest.raises(InputError, match=r"look like mg"):
        convert_csv(csv, tmp_path / "g.mcap", CsvLayout(accel_unit="g"))
    layout = CsvLayout(accel_unit="g", check_units=False)
    convert_csv(csv, tmp_path / "g.mcap", layout, replace=True)


@pytest.mark.parametrize("encoding", ["json", "ros2"])
def test_gyro_and_temperature_columns(session, tmp_path, encoding):
    gyro_dps = np.degrees(session.gyro_radps)
    header = ["Time", "Acc_X", "Acc_Y", "Acc_Z", "Gyr_X", "Gyr_Y", "Gyr_Z", "Temperature"]
    columns = [
        session.time_s.tolist(),
        *session.accel_mps2.T.tolist(),
        *gyro_dps.T.tolist(),
        session.temperature_c.tolist(),
    ]
    csv = tmp_path / "imu.csv"
    _write_csv(csv, header, columns, delimiter=";")
    out = tmp_path / "imu.mcap"
    base = ["convert", str(csv), str(out), "--accel-unit", "m/s^2", "--format", encoding]
    assert main(base) == 1  # a gyro without a stated unit
    assert not out.exists()
    assert main([*base, "--gyro-unit", "rad/s"]) == 1  # deg/s data stated as rad/s
    assert main([*base, "--gyro-unit", "deg/s", "--radius", "0.28"]) == 0
    back = read_recording(out)
    np.testing.assert_allclose(back.gyro_radps, session.gyro_radps, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(back.temperature_c, session.temperature_c, atol=1e-12)
    # A re-run replaces wheelcal's own output of the same CSV (issue 40; refused in issue 28)
    assert main([*base, "--no-gyro"]) == 0
    assert read_recording(out, info_overrides={"radius_m": 0.28}).gyro_radps is None
    # Columns given by name (any case) when their names are not recognised.
    renamed = ["Time", "Acc_X", "Acc_Y", "Acc_Z", "wx", "wy", "wz", "T_board"]
    _write_csv(csv, renamed, columns, delimiter=";")
    args = [
        "--gyro-columns",
        "WX",
        "WY",
        "WZ",
        "--gyro-unit",
        "deg/s",
        "--temperature-column",
        "t_board",
    ]
    assert main([*base, *args, "--force"]) == 0
    np.testing.assert_allclose(
        read_recording(out, info_overrides={"radius_m": 0.28}).gyro_radps,
        session.gyro_radps,
        rtol=1e-14,
        atol=1e-15,
    )


def test_ambiguous_or_missing_columns_name_the_file_and_the_columns(session, tmp_path):
    rows = [session.time_s.tolist(), *session.accel_mps2.T.tolist()]
    csv = tmp_path / "two.csv"
    _write_csv(csv, ["t", "ax", "acc_y", "az"], rows)
    convert_csv(csv, tmp_path / "ok.mcap", CsvLayout(accel_unit="m/s^2"))  # mixed styles are fine
    _write_csv(csv, ["t", "ax", "ay", "Acc_X"], rows)
    with pytest.raises(
        InputError, match=r"two\.csv: several accel columns for x: \['ax', 'Acc_X'\]"
    ):
        convert_csv(csv, tmp_path / "x.mcap", CsvLayout(accel_unit="m/s^2"))
    _write_csv(csv, ["clock", "ax", "ay", "az"], rows)
    with pytest.raises(InputError, match=r"two\.csv: no time column recognised.*--time-column"):
        convert_csv(csv, tmp_path / "x.mcap", CsvLayout(accel_unit="m/s^2"))
    _write_csv(csv, ["t", "Acc_X (m/s^2)", "Acc_Y (m/s^2)", "q"], rows)
    with pytest.raises(InputError, match=r"two\.csv: no column 'Acc_Z' \(accel z\)"):
        convert_csv(csv, tmp_path / "x.mcap", CsvLayout(accel_unit="m/s^2"))
    assert not (tmp_path / "x.mcap").exists()
