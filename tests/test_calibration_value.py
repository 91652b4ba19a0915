"""One calibration value (issue 41 item 5): typed, frozen fields parsed once, the same
in the process that computed the calibration and in one that read its file back.

``Calibration`` is built from the document ``calibration_dict`` makes of the session;
its fields (the sensor's numbers, the correction, warnings, undetermined, the closed
loop's diagnosis, a rolling wheel's lean, the source, bench and fit figures) are
values, not accessors re-parsing the JSON: the same object every read, read-only,
equal to the session's own numbers and to the reloaded file's.  The document is
written from those fields (``to_dict``/``to_json``), and it is still the very
document the session gave.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import json
import math

import numpy as np
import pytest

import wheelcal
from wheelcal.calibration.document import Calibration
from wheelcal.calibration.values import (
    AddedEffect,
    CalibrationDiagnosis,
    CalibrationFacts,
    frozen_array,
)
from wheelcal.model import AXES
from wheelcal.session import LeanReport
from wheelcal.simulate import car_drive, simulate_field


@functools.cache
def _warmup():
    """A bench spin whose offsets warm up: the closed loop adds ``offset_warmup``."""
    from test_one_answer import _session

    return wheelcal.calibrate(_session("warmup", False).recording)


@functools.cache
def _car():
    rng = np.random.default_rng(11)
    return wheelcal.calibrate(simulate_field(car_drive(rng), rng).recording)


def _reloaded(cal: Calibration, tmp_path) -> Calibration:
    return Calibration.from_json(cal.to_json(tmp_path / "c.calibration.json", durable=False))


def test_the_fields_are_parsed_once_and_read_only():
    cal = _warmup()
    assert cal.gain is cal.gain and cal.correction is cal.correction
    for name in ("gain", "offset_mps2", "gain_std", "offset_std_mps2", "systematic_gain_std"):
        with pytest.raises(ValueError):
            getattr(cal, name)[0] = 0.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        cal.gain = np.ones(3)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cal.diagnosis = None


def test_the_fields_are_the_sessions_numbers():
    cal = _warmup()
    result, session = cal.result, cal.session
    for i, axis in enumerate(AXES):
        assert cal.gain[i] == result.value_of(f"gain_{axis}")
        assert cal.offset_mps2[i] == result.value_of(f"offset_{axis}_mps2")
        assert cal.gain_std[i] == result.std_of(f"gain_{axis}")
        assert cal.offset_std_mps2[i] == result.std_of(f"offset_{axis}_mps2")
    budget = dict(zip(result.systematic.names, result.systematic.total_std, strict=True))
    assert list(cal.systematic_gain_std) == [budget[f"gain_{a}"] for a in AXES]
    assert cal.warnings == session.warnings
    assert cal.undetermined == session.assessment.undetermined == ()
    np.testing.assert_array_equal(cal.correction.matrix, cal.document["correction"]["matrix"])


def test_the_diagnosis_is_the_closed_loops_steps_with_their_evidence():
    cal = _warmup()
    loop = cal.closed_loop  # the whole report, in this process only
    diagnosis = cal.diagnosis
    assert isinstance(diagnosis, CalibrationDiagnosis)
    assert diagnosis.model == "closed_loop" and diagnosis.alpha == loop.alpha
    assert diagnosis.added == tuple(s.test.effect.label() for s in loop.steps)
    assert "offset_warmup" in {s.name for s in diagnosis.steps}
    by_name = {s.test.effect.name: s.test for s in loop.steps}
    assert {s.name for s in diagnosis.steps} == set(by_name)
    for step in diagnosis.steps:
        test = by_name[step.name]
        assert step == AddedEffect(
            step.name,
            test.statistic,
            test.dof,
            test.p_value,
            test.p_corrected,
            test.streams,
        )
        assert step.p_corrected < diagnosis.alpha
    assert diagnosis.smallest_p_corrected == min(
        t.p_corrected for t in loop.final_tests if t.identifiable
    )
    assert diagnosis.not_identifiable == tuple(t.effect.label() for t in loop.not_identifiable)


def test_the_papers_model_has_no_diagnosis(table1_session):
    cal = wheelcal.calibrate(table1_session.recording, model="paper")
    assert cal.diagnosis is None and cal.closed_loop is None and cal.lean is None


def test_a_rolling_wheels_lean_is_the_sessions(tmp_path):
    cal = _car()
    lean, own = cal.lean, cal.session.lean
    assert isinstance(lean, LeanReport) and own is not None
    assert lean.change_deg == own.change_deg
    assert lean.in_turns_deg_per_mps2 == own.in_turns_deg_per_mps2
    assert lean.in_turns_std_deg_per_mps2 == own.in_turns_std_deg_per_mps2
    assert lean.track == own.track
    if own.check is not None:
        assert (lean.check.statistic, lean.check.dof) == (own.check.statistic, own.check.dof)
        assert dict(lean.check.shift_sigma) == pytest.approx(own.check.shift_sigma)
        assert lean.check.moved(3.0, 0.5) == own.check.moved(3.0, 0.5)
        with pytest.raises(TypeError):
            lean.check.shift_sigma["gain_x"] = 0.0
    assert cal.diagnosis is None  # a wheel in the field: no closed loop
    assert _reloaded(cal, tmp_path).lean == lean


@pytest.mark.parametrize("which", ["bench", "car"])
def test_the_reloaded_file_carries_the_same_values_and_writes_the_same_document(which, tmp_path):
    cal = _warmup() if which == "bench" else _car()
    back = _reloaded(cal, tmp_path)
    assert back.session is None and back.closed_loop is None
    for name in (
        "gain",
        "offset_mps2",
        "gain_std",
        "offset_std_mps2",
        "systematic_gain_std",
        "systematic_offset_std_mps2",
    ):
        np.testing.assert_array_equal(getattr(back, name), getattr(cal, name), err_msg=name)
    np.testing.assert_array_equal(back.correction.matrix, cal.correction.matrix)
    np.testing.assert_array_equal(back.correction.bias_mps2, cal.correction.bias_mps2)
    assert (back.warnings, back.undetermined, back.kind) == (
        cal.warnings,
        cal.undetermined,
        cal.kind,
    )
    assert back.diagnosis == cal.diagnosis and back.lean == cal.lean
    # the saved document: byte for byte the one written, and the Mapping still reads it
    first = (tmp_path / "c.calibration.json").read_text(encoding="utf-8")
    again = back.to_json(tmp_path / "again.calibration.json", durable=False)
    assert again.read_text(encoding="utf-8") == first
    assert json.loads(first) == cal.to_dict() == dict(back.items())
    assert back["sensor"]["gain"] == [None if math.isnan(g) else g for g in cal.gain]


def test_the_smallest_sensor_document_reads_with_nan_sigma():
    document = {
        "format": "wheelcal.sensor_calibration/1",
        "sensor": {"gain": [1.0, 1.0, 1.0], "offset_mps2": [0.0, 0.0, 0.0], "undetermined": []},
        "correction": {"bias_mps2": [0.1, 0.2, 0.3], "matrix": np.eye(3).tolist()},
    }
    cal = Calibration(document)
    assert cal.kind == "sensor" and cal.warnings == () and cal.diagnosis is None
    assert np.all(np.isnan(cal.gain_std)) and np.all(np.isnan(cal.systematic_offset_std_mps2))
    np.testing.assert_array_equal(cal.correction.bias_mps2, [0.1, 0.2, 0.3])


@pytest.mark.parametrize("which", ["bench", "car"])
def test_the_document_is_written_from_the_typed_fields(which):
    """A field changed (behind the frozen dataclass's back) is what to_dict writes."""
    cal = _warmup() if which == "bench" else _car()
    assert cal.to_dict() == dict(cal.items())  # the same document the session gave
    changed = copy.copy(cal)
    object.__setattr__(changed, "gain", frozen_array([2.0, float("nan"), 3.0]))
    object.__setattr__(changed, "warnings", ("a warning of the field's",))
    facts = dataclasses.replace(cal.facts, tilt_deg=12.5, window_s=(1.0, 2.0))
    object.__setattr__(changed, "facts", facts)
    if cal.lean is not None:
        object.__setattr__(changed, "lean", dataclasses.replace(cal.lean, change_deg=0.25))
    if cal.diagnosis is not None:
        object.__setattr__(changed, "diagnosis", dataclasses.replace(cal.diagnosis, alpha=0.5))
    doc = changed.to_dict()
    assert doc["sensor"]["gain"] == [2.0, None, 3.0]
    assert doc["fit"]["warnings"] == ["a warning of the field's"]
    assert doc["bench"]["tilt_deg"] == 12.5 and doc["source"]["window_s"] == [1.0, 2.0]
    if cal.lean is not None:
        assert doc["bench"]["lean"]["change_deg"] == 0.25
    if cal.diagnosis is not None:
        assert doc["fit"]["effects_screen"]["alpha"] == 0.5
        for step in cal.diagnosis.steps:
            assert doc["effects"][step.name]["evidence"]["alpha"] == 0.5
    # the keys no field holds, and the order of every key, stay the document's
    assert list(doc) == list(cal.document)
    assert doc["fit"]["covariance"] == cal["fit"]["covariance"]


def test_the_sessions_figures_are_fields_and_a_sensors_document_refuses_them():
    cal = _warmup()
    facts = cal.facts
    assert isinstance(facts, CalibrationFacts) and cal.facts is facts
    assert cal.tilt_deg == cal.document["bench"]["tilt_deg"] == facts.tilt_deg
    assert cal.radius_m == cal.document["bench"]["radius_m"]
    assert cal.window_s == tuple(cal.document["source"]["window_s"])
    assert cal.source_file == cal.document["source"]["file"] == cal.session.source
    np.testing.assert_array_equal(
        cal.misalignment_matrix, cal.result.params.bench.misalignment.matrix
    )
    np.testing.assert_array_equal(cal.residual_rms_mps2, cal.result.residual_rms_mps2)
    with pytest.raises(ValueError):
        cal.misalignment_matrix[0, 0] = 0.0
    for name, (value, std) in cal.parameters.items():
        assert (value, std) == (cal.result.value_of(name), cal.result.std_of(name))
    sensor = Calibration(
        {
            "format": "wheelcal.sensor_calibration/1",
            "source": {"sensor_id": "A", "mounting_ids": ["m1", "", "m2"]},
            "sensor": {"gain": [1.0] * 3, "offset_mps2": [0.0] * 3, "undetermined": []},
            "correction": {"bias_mps2": [0.0] * 3, "matrix": np.eye(3).tolist()},
        }
    )
    assert (sensor.sensor_id, sensor.mounting_id) == ("A", "m1, m2")
    for name in ("tilt_deg", "radius_m", "window_s", "source_file", "residual_rms_mps2"):
        with pytest.raises(ValueError, match="pooled calibration"):
            getattr(sensor, name)
