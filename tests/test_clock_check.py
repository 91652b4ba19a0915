"""Issue 40, item 6: a sample clock that is off is named, not absorbed into the gains.

A free spin cannot see a clock error: stamps × 0.98 (the clock 2 % slow) made
every gain 4 % low, 11 σ with the systematic σ, exit 0 and no warning, with or
without a gyro.  Now the stamped rate is judged against its nominal rate
(:mod:`wheelcal.session.clock_check`) and, with a gyro, the gyro's reading of
the wheel against the accelerometer's fit.  The predicted bias is checked
against the simulator's truth; a clean recording and a 120.0048 Hz one (an
Xsens DOT's stamped rate) are not flagged.
"""

import json

import numpy as np
import pytest

from wheelcal.cli.main import main
from wheelcal.io import write_recording
from wheelcal.recording import CalibrationRefused
from wheelcal.session.clock_check import nominal_rate, stamped_rate_hz
from wheelcal.session.compute import SessionOptions, compute_recording
from wheelcal.simulate import hostile as H
from wheelcal.simulate.gyro import GyroSpec


@pytest.fixture(scope="module")
def plain():
    return H.clean(np.random.default_rng(2))


@pytest.fixture(scope="module")
def with_gyro():
    return H.clean(np.random.default_rng(2), gyro=GyroSpec())


def _gains(session):
    return np.array([session.result.value_of(f"gain_{a}") for a in "xyz"])


def _clock_warnings(session):
    return [w for w in session.warnings if w.startswith("clock:")]


@pytest.mark.parametrize("which", ["plain", "with_gyro"])
def test_stamps_scaled_by_0_98_are_warned_by_name(request, which):
    truth = request.getfixturevalue(which)
    session = compute_recording(H.clock_scaled(truth, 0.98, "slow"), SessionOptions())
    check = session.assessment.clock
    assert check.verdict == "rate_off"
    assert check.nominal_rate_hz == 200.0
    assert check.rate_offset == pytest.approx(1 / 0.98 - 1, rel=1e-6)
    (warning,) = _clock_warnings(session)
    assert (
        "204.082 Hz, 2.04 % above the nominal 200 Hz" in warning and "runs 2.04 % slow" in warning
    )
    # The predicted bias (first order, from the systematic budget) is the bias the
    # simulator's truth shows: the gains ≈ 4 % low, ~11 σ.
    error = _gains(session) - np.asarray(truth.truth.sensor.gain)
    axis = "xyz".index(check.worst[-1])
    assert check.worst.startswith("gain_")
    assert check.worst_shift == pytest.approx(error[axis], rel=0.05)
    assert np.all(error < -0.035) and check.bias_sigmas > 8


def test_a_clean_recording_is_not_flagged(plain, with_gyro):
    for truth in (plain, with_gyro):
        session = compute_recording(truth.recording, SessionOptions())
        assert session.assessment.clock.verdict == "ok" and not _clock_warnings(session)


def test_a_clock_fast_by_2_4_percent_is_refused_when_the_gyro_confirms_it(with_gyro):
    with pytest.raises(
        CalibrationRefused, match=r"refused \(clock\): .*195\.\d+ Hz, 2\.40 % below"
    ) as exc:
        compute_recording(H.clock_scaled(with_gyro, 1.0246, "fast"), SessionOptions())
    assert "the gyro confirms it" in exc.value.reason and "--clock-tolerance" in exc.value.fix
    # … and the tolerance lets a user who knows better through, the gyro's 3.4 % still said
    gates = SessionOptions().gates.__class__(clock_tolerance=0.03)
    session = compute_recording(
        H.clock_scaled(with_gyro, 1.0246, "fast"), SessionOptions(gates=gates)
    )
    assert session.assessment.clock.verdict == "gyro_off"
    (warning,) = _clock_warnings(session)
    assert "the gyro reads the wheel's rate with scale 1.03" in warning


def test_a_sensor_that_really_samples_off_nominal_is_cleared_by_its_gyro():
    """204.08 Hz true sampling, stamps right: the gyro agrees with the stamps."""
    truth = H.clean(np.random.default_rng(2), rate_hz=200 / 0.98, gyro=GyroSpec())
    session = compute_recording(truth.recording, SessionOptions())
    check = session.assessment.clock
    assert check.verdict == "cleared" and check.likelihood_ratio < 1 / 20
    assert not _clock_warnings(session)


def test_the_stamped_rate_of_an_xsens_dot_is_its_nominal_rate():
    """120.0048 Hz, µs stamps (the WID car drives' SampleTimeFine): 40 ppm, not judged."""
    t_us = np.floor(np.arange(16_000) * 1e6 / 120.0048)
    rate = stamped_rate_hz(t_us * 1e-6)
    assert rate == pytest.approx(120.0048, abs=2e-4)
    nominal, offset = nominal_rate(rate)
    assert nominal == 120.0 and abs(offset) < 1e-4
    truth = H.clean(np.random.default_rng(5), rate_hz=120.0048, gyro=GyroSpec())
    session = compute_recording(truth.recording, SessionOptions())
    assert session.assessment.clock.verdict == "ok" and not _clock_warnings(session)


def test_the_calibration_json_states_the_clock_check_and_what_the_budget_assumes(
    tmp_path, plain, capsys
):
    path = tmp_path / "slow.mcap"
    write_recording(H.clock_scaled(plain, 0.98, "slow"), path)
    assert main(["calibrate", str(path), "--out", str(tmp_path / "out")]) == 0
    assert "clock: the samples are stamped at 204.08" in capsys.readouterr().out
    doc = json.loads((tmp_path / "out" / "slow.calibration.json").read_text())
    check = doc["fit"]["clock_check"]
    assert check["verdict"] == "rate_off" and check["nominal_rate_hz"] == 200.0
    assert check["rate_offset_ppm"] == pytest.approx(20408.2, abs=0.5)
    assumes = doc["systematic"]["sources"]["sample_clock"]["assumes"]
    assert "±100 ppm" in assumes and "fit.clock_check" in assumes
    assert any(w.startswith("clock:") for w in doc["fit"]["warnings"])
