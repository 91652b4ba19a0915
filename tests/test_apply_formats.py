"""``wheelcal apply`` on every format ``calibrate`` reads, one message out per message in.

* A ROS 1 ``.bag`` and a rosbag2 ``.db3`` (written by rosbags' own writers) become an
  MCAP with their IMU topic copied (raw values and gyro, as read) and the calibrated
  topic: the correction of every sample, the counts in = out.
* A session clipped at its ±4 g rail keeps every sample: the ones the calibration's
  reader drops are corrected too and flagged ``clipped`` (as many as its note says, each
  at the rail), and the command line says so; a repeated stamp and a NaN are counted.
* ``--gyro-counts-per-dps``: a CSV log with raw gyro counts (an Arduino's) keeps its gyro.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from robot_logs import imu_messages, write_bag, write_db3
from wheelcal.calibration.session_json import load_calibration, load_correction_from
from wheelcal.cli.main import main
from wheelcal.io import read_recording
from wheelcal.io.mcap_reader import read_raw_samples
from wheelcal.io.mcap_scan import scan_mcap

FLAGS = "/imu/data_raw/calibrated/flags"


@pytest.fixture(scope="module")
def calibration(tmp_path_factory):
    """A session with a gyro, calibrated; (its MCAP, its calibration JSON)."""
    d = tmp_path_factory.mktemp("apply")
    rec = d / "spin.mcap"
    assert main(["simulate", str(rec), "--gyro", "--seed", "4"]) == 0
    assert main(["calibrate", str(rec), "--out", str(d), "--quiet"]) == 0
    return rec, d / "spin.calibration.json"


def _flags(path):
    """The flag messages of an apply output, as (stamp, reason)."""
    from mcap.reader import make_reader

    with open(path, "rb") as stream:
        return [
            (json.loads(m.data)["timestamp_ns"], json.loads(m.data)["reason"])
            for _, c, m in make_reader(stream).iter_messages(topics=[FLAGS])
        ]


@pytest.mark.parametrize("kind", ["bag", "db3"])
def test_apply_reads_a_robot_log_and_writes_every_sample(calibration, tmp_path, kind, capsys):
    rec, cal = calibration
    source = read_raw_samples(rec)
    part = slice(2000, 4000)  # applying needs no spin: 10 s of the recording
    time_ns, accel, gyro = source.time_ns[part], source.accel_mps2[part], source.gyro_radps[part]
    messages = imu_messages(time_ns, accel, gyro, ros1=kind == "bag")
    if kind == "bag":
        log = write_bag(tmp_path / "log.bag", time_ns, messages)
    else:
        log = write_db3(tmp_path / "log", time_ns, messages)
    out = tmp_path / "calibrated.mcap"
    assert main(["apply", str(cal), str(log), str(out)]) == 0
    said = capsys.readouterr().out
    assert "2000 messages in, 2000 calibrated on /imu/data_raw/calibrated" in said
    assert "copied as ROS 2 sensor_msgs/msg/Imu" in said
    correction = load_correction_from(load_calibration(cal))
    calibrated = read_raw_samples(out, "/imu/data_raw/calibrated")
    np.testing.assert_array_equal(calibrated.time_ns, time_ns)
    np.testing.assert_allclose(calibrated.accel_mps2, correction.apply(accel), rtol=0, atol=1e-12)
    copied = read_raw_samples(out, "/imu/data_raw")  # the log's own topic, as read
    np.testing.assert_array_equal(copied.accel_mps2, accel)
    np.testing.assert_array_equal(copied.gyro_radps, gyro)
    record = dict(dict(scan_mcap(out).metadata)["wheelcal.apply"])
    assert record["messages_in"] == record["samples_out"] == "2000"
    assert _flags(out) == []


def test_a_clipped_session_keeps_every_sample_and_flags_the_clipped(tmp_path, capsys):
    rec, cal = tmp_path / "clipped.mcap", tmp_path / "cal"
    assert main(["simulate", str(rec), "--quantise", "--seed", "4"]) == 0  # ±4 g: 16 % clip
    assert main(["calibrate", str(rec), "--out", str(cal), "--quiet"]) == 0
    recording = read_recording(rec)
    (note,) = [n for n in recording.notes if "clipped" in n]
    dropped = int(re.search(r"dropped (\d+) clipped", note).group(1))
    out = tmp_path / "out.mcap"
    assert main(["apply", str(cal / "clipped.calibration.json"), str(rec), str(out)]) == 0
    said = capsys.readouterr().out
    raw = read_raw_samples(rec)
    n = raw.time_ns.size
    assert f"{n} messages in, {n} calibrated" in said
    assert f"{dropped} clipped" in said and "the force was larger" in said
    calibrated = read_raw_samples(out, "/imu/data_raw/calibrated")
    assert calibrated.time_ns.size == n
    flags = _flags(out)
    assert len(flags) == dropped and {why for _, why in flags} == {"clipped"}
    # each flagged sample sits at the rail the reader found; no kept one is flagged
    rail = np.nanmax(recording.clip_limits_mps2)
    at = np.isin(raw.time_ns, [t for t, _ in flags])
    assert np.all(np.max(raw.accel_mps2[at], axis=1) >= 0.995 * rail)
    assert not np.any(
        np.isin(recording.epoch_unix_ns + np.rint(recording.time_s * 1e9), raw.time_ns[at])
    )


def test_repeated_stamps_and_nans_are_counted(calibration, tmp_path, capsys):
    from wheelcal.io.mcap_writer import write_accel_mcap

    rec, cal = calibration
    raw = read_raw_samples(rec)
    time_ns, accel = raw.time_ns[:3000].copy(), raw.accel_mps2[:3000].copy()
    time_ns[101] = time_ns[100]  # a repeated stamp
    accel[200] = np.nan  # no value
    path = tmp_path / "defects.mcap"
    write_accel_mcap(path, time_ns, accel)
    out = tmp_path / "out.mcap"
    assert main(["apply", str(cal), str(path), str(out)]) == 0
    said = capsys.readouterr().out
    assert "3000 messages in, 2999 calibrated" in said
    assert "1 repeated stamp" in said and "not written: 1 with no value (NaN or inf)" in said
    assert _flags(out) == [(int(time_ns[101]), "repeated stamp")]


def test_raw_gyro_counts_are_read_with_their_scale(tmp_path, capsys):
    """An Arduino's ``millis,ax,ay,az,gx,gy,gz``: int16 counts (±8 g, ±2000 °/s), gyro kept."""
    from wheelcal.simulate import GyroSpec, table2
    from wheelcal.simulate.session import simulate_session

    rng = np.random.default_rng(22)
    scenario = table2(rng=rng)
    scenario = type(scenario)(**{**scenario.__dict__, "gyro": GyroSpec(full_scale_dps=2000.0)})
    rec = simulate_session(scenario, rng).recording
    g, per_g, per_dps = 9.80665, 4096, 16.4
    accel = np.clip(np.round(rec.accel_mps2 / g * per_g), -32768, 32767).astype(np.int64)
    gyro = np.round(np.degrees(np.nan_to_num(rec.gyro_radps)) * per_dps).astype(np.int64)
    millis = np.round(rec.time_s * 1e3).astype(np.int64)
    rows = [
        ",".join(map(str, (t, *a, *w)))
        for t, a, w in zip(millis.tolist(), accel.tolist(), gyro.tolist(), strict=True)
    ]
    csv = tmp_path / "log.csv"
    csv.write_text("millis,ax,ay,az,gx,gy,gz\r\n" + "\r\n".join(rows) + "\r\n")
    out = tmp_path / "log.mcap"
    args = ["--accel-unit", "counts", "--counts-per-g", "4096", "--radius", "0.28"]
    args += ["--gyro-full-scale-dps", "2000"]  # the range stated: no rail to guess
    assert main(["convert", str(csv), str(out), *args, "--gyro-counts-per-dps", "16.4"]) == 0
    assert "converted gyro counts to °/s (16.4 per °/s)" in capsys.readouterr().out
    back = read_recording(out)
    assert back.gyro_radps is not None
    np.testing.assert_allclose(back.gyro_radps, np.radians(gyro / per_dps), rtol=1e-12)
    # a count is 1/16.4 °/s: the gyro reads the simulated rate to half of that
    valid = np.all(np.isfinite(rec.gyro_radps), axis=1)
    error = np.degrees(np.abs(back.gyro_radps[valid] - rec.gyro_radps[valid]))
    assert np.max(error) <= 0.5 / per_dps + 1e-9
    # … and calibrates with it
    assert main(["calibrate", str(out), "--out", str(tmp_path / "cal"), "--quiet"]) == 0
    doc = json.loads((tmp_path / "cal" / "log.calibration.json").read_text())
    assert "gyro" in doc and doc["imu_noise"]["gyroscope"]["samples"] > 0
    assert (
        main(
            [
                "convert",
                str(csv),
                str(tmp_path / "x.mcap"),
                *args,
                "--gyro-unit",
                "rad/s",
                "--gyro-counts-per-dps",
                "16.4",
            ]
        )
        == 2
    )  # a scale for counts, not for rad/s
