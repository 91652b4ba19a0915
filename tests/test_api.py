"""The Python API (issue 14): the README example runs, refusals raise, options are checked."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import wheelcal
from wheelcal.simulate import hostile as H

ROOT = Path(__file__).resolve().parents[1]


def test_the_readme_python_example_runs(tmp_path, monkeypatch, capsys):
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)\n```", text, flags=re.S)
    (example,) = [b for b in blocks if "wheelcal.calibrate(" in b]
    monkeypatch.chdir(tmp_path)
    exec(compile(example, "README.md", "exec"), {})  # the README's own code
    out = capsys.readouterr().out
    assert "gain_range" in out and "measure the radius" in out and "0.283" not in out
    assert (tmp_path / "spin.calibration.json").exists()


@pytest.fixture(scope="module")
def session():
    return H.clean(np.random.default_rng(71))


def test_calibrate_a_recording_in_memory_matches_the_truth(session):
    cal = wheelcal.calibrate(session.recording, radius_m=0.28)
    truth = session.truth.sensor
    assert np.all(np.abs(cal.gain - truth.gain) < 5 * cal.gain_std + 1e-4)
    assert cal.result is not None and cal.result.assessment is not None
    corrected = cal.apply(session.recording.accel_mps2)
    assert corrected.shape == session.recording.accel_mps2.shape


def test_a_refusal_raises_with_gate_reason_and_fix(session):
    with pytest.raises(wheelcal.CalibrationRefused) as info:
        wheelcal.calibrate(session.recording, radius_m=0.028)
    assert info.value.gate in ("unit", "gain_range")
    assert "radius" in info.value.reason and info.value.fix


def test_a_misspelt_option_is_a_type_error(session):
    with pytest.raises(TypeError, match="radus"):
        wheelcal.calibrate(session.recording, radius_m=0.28, radus=1.0)


def test_a_partial_calibration_applies_only_when_allowed(tmp_path):
    s = H.axis_near_wheel_axis(np.random.default_rng(11), 1.0)
    cal = wheelcal.calibrate(s.recording, radius_m=0.28)
    assert {name for name, _ in cal.undetermined} == {"gain_z", "offset_z_mps2"}
    assert np.isnan(cal.gain[2]) and np.isfinite(cal.gain[0])
    with pytest.raises(ValueError, match="allow_partial"):
        cal.apply(s.recording.accel_mps2)
    corrected = cal.apply(s.recording.accel_mps2, allow_partial=True)
    np.testing.assert_array_equal(corrected[:, 2], s.recording.accel_mps2[:, 2])
    path = cal.to_json(tmp_path / "partial.calibration.json")
    back = wheelcal.Calibration.from_json(path)
    assert back.undetermined == cal.undetermined


def test_diagnose_returns_the_calibration_with_its_closed_loop(session):
    cal = wheelcal.diagnose(session.recording, radius_m=0.28)
    assert cal.diagnosis is not None
    assert cal.diagnosis.steps == ()  # a clean recording needs no effect


def test_the_calibration_object_is_immutable(session):
    cal = wheelcal.calibrate(session.recording, radius_m=0.28)
    with pytest.raises(TypeError):
        cal.document["sensor"] = {}
    with pytest.raises(ValueError):
        cal.gain[0] = 2.0


def test_wheelcal_diagnose_is_the_api_even_after_the_package_is_imported(session):
    import wheelcal.closedloop.loop

    cal = wheelcal.diagnose(session.recording, radius_m=0.28)
    assert cal.diagnosis is not None
