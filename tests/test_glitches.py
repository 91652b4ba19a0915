"""One bad sample never costs a recording: a logger's glitches are left out, with a note.

A gyro sample of 3.7·10⁷ rad/s (a bit error; a real drive was lost to one), rows of
exact zeros before the sensor's first reading (a logger's start), and a sensor
that was never read at all (every row zero: refused by name).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from loop_truth import sigmas_from_truth
from wheelcal.cli.main import main
from wheelcal.io import read_recording, write_recording
from wheelcal.simulate import hostile
from wheelcal.simulate.gyro import GyroSpec


@pytest.fixture(scope="module")
def session():
    return hostile.clean(np.random.default_rng(3), gyro=GyroSpec())


def _glitched(session, zeros: int = 20, spike_radps: float | None = 3.7e7):
    rec = session.recording
    gyro, accel = rec.gyro_radps.copy(), rec.accel_mps2.copy()
    if spike_radps is not None:
        gyro[7000, 2] = spike_radps
    accel[:zeros], gyro[:zeros] = 0.0, 0.0
    return dataclasses.replace(rec, gyro_radps=gyro, accel_mps2=accel)


def test_a_gyro_glitch_and_leading_zero_rows_cost_nothing(session, tmp_path):
    path = tmp_path / "glitch.mcap"
    write_recording(_glitched(session), path)
    read = read_recording(path)
    assert read.time_s.size == session.recording.time_s.size - 20
    assert np.all(np.isnan(read.gyro_radps[7000 - 20])), "the glitch is left out"
    assert np.isfinite(read.gyro_radps[7001 - 20]).all()
    notes = " ".join(read.notes)
    assert "dropped the first 20 samples" in notes and "a logger's glitch" in notes
    assert main(["calibrate", str(path), "--out", str(tmp_path / "out")]) == 0
    doc = json.loads((tmp_path / "out" / "glitch.calibration.json").read_text())
    assert any("glitch" in n for n in doc["source"]["notes"])
    import wheelcal

    cal = wheelcal.calibrate(read)
    assert max(abs(v) for v in sigmas_from_truth(session, cal.result).values()) < 5


def test_a_sensor_never_read_is_refused_by_name(session, tmp_path):
    path = tmp_path / "zeros.mcap"
    rec = session.recording
    write_recording(dataclasses.replace(rec, accel_mps2=np.zeros_like(rec.accel_mps2)), path)
    with pytest.raises(Exception, match="every sample reads exactly 0 on all three axes"):
        read_recording(path)
    assert main(["calibrate", str(path), "--out", str(tmp_path / "out")]) == 1


def test_many_wild_gyro_samples_are_a_unit_error_not_glitches(session, tmp_path):
    # Glitches are few and isolated; a channel in °/s labelled rad/s is refused as before.
    rec = session.recording
    path = tmp_path / "dps.mcap"
    write_recording(dataclasses.replace(rec, gyro_radps=rec.gyro_radps * 180 / np.pi * 60), path)
    with pytest.raises(Exception, match="beyond any MEMS"):
        read_recording(path)
