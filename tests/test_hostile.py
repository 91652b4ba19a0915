"""Well-formed but hostile recordings: refused with their reason, warned, or right (issue 11).

Every case ends in one of three acceptable ways:

* **refused** — :class:`CalibrationRefused` naming the expected gate, the reason
  mentioning the cause (e.g. "radius");
* **warned** — accepted, with a warning that names the cause;
* **right** — accepted, every determined gain and offset within 5 σ_CRLB of the
  truth (the bound at the truth, tests/truth_bound.py), undetermined ones null.

A *confident wrong answer* — accepted without a warning naming the cause and
> 5 σ_CRLB off, or a value for a parameter the recording cannot determine — fails.
"""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest

from truth_bound import sigmas_off
from wheelcal.recording import CalibrationRefused
from wheelcal.session.fit import SessionFit
from wheelcal.simulate import hostile as H

RIGHT_SIGMA = 5.0


def _run(recording):
    return SessionFit().run(recording).result


def _refused(recording, gate: str | tuple[str, ...], *words: str) -> CalibrationRefused:
    with pytest.raises(CalibrationRefused) as info:
        _run(recording)
    gates = (gate,) if isinstance(gate, str) else gate
    assert info.value.gate in gates, str(info.value)
    for word in words:
        assert word in str(info.value), str(info.value)
    assert info.value.fix, "a refusal names the likely fix"
    return info.value


def _right(session, result, undetermined: tuple[str, ...] = ()):
    assert set(result.undetermined) == set(undetermined), result.undetermined
    off = sigmas_off(session, result)
    assert max(off.values()) < RIGHT_SIGMA, off
    return off


def _rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


@pytest.fixture(scope="module")
def clean_session():
    return H.clean(_rng(2))


@pytest.mark.parametrize("factor", [0.1, 1000.0, 1e9])
def test_a_radius_in_the_wrong_unit_is_refused_naming_the_radius(clean_session, factor):
    rec = clean_session.recording
    rec = replace(rec, info=rec.info.merged(radius_m=0.28 * factor))
    error = _refused(rec, ("gain_range", "unit"), "radius")
    # the reason names the radius the data imply (the true 0.28 m, to the gains' spread) as a
    # diagnosis; the fix asks for a measured radius and never offers that number to copy
    # (issue 28: copying 0.283 for a true 0.280 biases every gain by 1 %)
    assert "0.28" in error.reason and "only if the gains were exactly 1" in error.reason
    assert "measure the radius" in error.fix
    assert not re.search(r"--radius\s+[0-9]", error.fix) and not re.search(r"0\.2[0-9]", error.fix)


def test_a_radius_7_percent_off_is_accepted_with_a_warning_naming_the_radius(clean_session):
    rec = clean_session.recording
    result = _run(replace(rec, info=rec.info.merged(radius_m=0.28 * 1.07)))
    radius_warnings = [w for w in result.warnings if "radius" in w]
    assert radius_warnings, result.warnings
    # the implied radius r·γ̄: the true 0.28 m times the true gains' mean 1.0104
    assert "radius is 0.283 m" in radius_warnings[0]


@pytest.mark.parametrize("factor, words", [(1 / 9.80665, ("g", "m/s²")), (9.80665, ("m/s²",))])
def test_a_mislabelled_unit_is_refused_naming_the_unit(clean_session, factor, words):
    rec = H.rescaled(clean_session, factor, "mislabelled")
    _refused(rec, "unit", "unit", *words)


@pytest.mark.parametrize("rate_hz", [1.0, 5.0])
def test_a_spin_sampled_too_slowly_is_refused(rate_hz):
    _refused(H.sampled_at(_rng(4), rate_hz).recording, "sampling", "samples per turn")


def test_a_spin_sampled_at_20_hz_is_calibrated_right():
    session = H.sampled_at(_rng(4), 20.0)
    _right(session, _run(session.recording))


def test_a_30_minute_free_spin_is_calibrated_right_on_a_window_the_cubic_describes():
    session = H.long_spin(_rng(5), 1800.0)
    out = SessionFit().run(session.recording)
    assert out.result.window_s[1] - out.result.window_s[0] <= 300.0
    assert "capped" in out.window.reason
    _right(session, out.result)


@pytest.mark.slow
def test_an_hour_long_free_spin_is_calibrated_right():
    session = H.long_spin(_rng(15), 3600.0)
    _right(session, _run(session.recording))


def test_a_saturated_axis_with_jitter_is_found_and_calibrated_right(tmp_path):
    from wheelcal.io import read_recording, write_recording

    session = H.saturated(_rng(6))
    path = tmp_path / "saturated.mcap"
    write_recording(session.recording, path)
    recording = read_recording(path)
    assert any("clipped" in note for note in recording.notes), recording.notes
    _right(session, _run(recording))


def test_a_driven_wheel_rising_smoothly_is_calibrated_right():
    session = H.rising(_rng(7))
    _right(session, _run(session.recording))


def test_a_motor_holding_the_speed_with_steps_is_refused():
    # Between steps the speed is constant: r·ω² passes for an offset and no gain is
    # determined; the window finder never straddles a step.
    _refused(H.motor_steps(_rng(8)).recording, ("undetermined", "motion"))


def test_three_pushes_in_one_recording_are_calibrated_right_between_two_pushes():
    session = H.three_pushes(_rng(9))
    result = _run(session.recording)
    _right(session, result)


def test_a_motor_whose_speed_wanders_is_refused_for_its_motion():
    # ±5 % of slow wander looks like a free spin to the window finder, but no cubic
    # follows it, and no window short enough for one holds ten turns of evidence.
    for seed in (300, 301, 302):
        _refused(H.wandering(_rng(seed)).recording, "motion", "eq. (2)")


def test_a_vibrating_bench_is_calibrated_right_and_the_vibration_named():
    session = H.vibrating(_rng(10), 0.5)
    result = _run(session.recording)
    _right(session, result)
    assert any("vibrat" in w for w in result.warnings), result.warnings
    assert 5 < np.max(result.assessment.noise.ratio) < 8  # 0.5 m/s² on 0.08 m/s² of noise


def test_an_axis_within_1_degree_of_the_wheel_axis_is_reported_undetermined():
    session = H.axis_near_wheel_axis(_rng(11), 1.0)
    result = _run(session.recording)
    _right(session, result, undetermined=("gain_z", "offset_z_mps2"))


def test_an_axis_exactly_radial_leaves_the_other_two_gains_undetermined():
    session = H.axis_exactly_radial(_rng(12))
    result = _run(session.recording)
    _right(session, result, undetermined=("gain_y", "gain_z", "offset_y_mps2", "offset_z_mps2"))


def test_a_signal_the_model_cannot_describe_is_refused_as_a_misfit():
    # 1 m/s² at twice the wheel frequency on one axis (a loose mount rattling with the
    # turn): no parameter of the model makes it, and a fit that converges anyway leaves
    # it at the wheel's harmonics, 9× the sensor's noise.
    session = H.clean(_rng(13))
    rec = session.recording
    t = rec.time_s
    omega = session.omega_radps
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) * np.diff(t))])
    extra = np.zeros_like(rec.accel_mps2)
    extra[:, 1] = 1.0 * np.sin(2 * theta)
    _refused(replace(rec, accel_mps2=rec.accel_mps2 + extra), "misfit", "harmonics")
