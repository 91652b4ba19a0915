"""``--geometry auto`` decides from the evidence, and a refusal is an answer (issue 41, item 4).

:func:`~wheelcal.session.auto.decide_geometry` reads the cheap evidence first (a
gyroscope, the carrier's turning, a radius) and fits only where it leaves the
choice open; :meth:`SessionFit.attempt <wheelcal.session.fit.SessionFit.attempt>`
and :meth:`SessionFit.judge` answer with values, never by raising.  Which
recordings calibrate, and which are refused with what, is the end-to-end tests'
(``test_field_calibration``, ``test_refusal_cli``, ``test_gyro_passes``).
"""

from __future__ import annotations

import numpy as np
import pytest

from wheelcal.recording import CalibrationRefused, RecordingError
from wheelcal.session import SessionOptions
from wheelcal.session.auto import GeometryDecision, decide_geometry
from wheelcal.session.fit import GYRO_CAN_HELP, SessionFit
from wheelcal.simulate import simulate, table1


def test_without_a_gyroscope_the_bench_is_decided_before_any_fit():
    recording = simulate(table1(), np.random.default_rng(0)).recording
    decision = decide_geometry(recording, SessionOptions())
    assert decision.model == "bench" and decision.answer is None
    assert decision.reason.startswith("no gyroscope")


def test_a_refused_geometry_carries_its_refusal():
    with pytest.raises(ValueError, match="refusal"):
        GeometryDecision("refused", "a tilted fixed axle")
    with pytest.raises(ValueError, match="model must be one of"):
        GeometryDecision("rolling", "not a model")
    refusal = RecordingError("x.mcap: give --radius")
    assert GeometryDecision("refused", "tilted", refusal).answer is refusal


def test_the_accelerometers_refusal_is_judged_as_a_value():
    gate = GYRO_CAN_HELP[0]
    helped = SessionFit.judge(CalibrationRefused("x.mcap", gate, "a driven wheel", "fix"))
    assert helped == f"the accelerometer alone was refused ({gate}: a driven wheel)"
    other = CalibrationRefused("x.mcap", "units", "the gains are 9.8", "fix")
    assert SessionFit.judge(other) is other  # a refusal the gyro cannot help stands
    assert SessionFit.judge(RecordingError("no spin")) == "no free spin (no spin)"


def test_an_attempt_returns_the_refusal_instead_of_raising():
    recording = simulate(table1(), np.random.default_rng(0)).recording
    answer = SessionFit(gyro="on").attempt(recording)  # no gyroscope in the recording
    assert isinstance(answer, RecordingError) and "no usable gyroscope" in str(answer)
    with pytest.raises(RecordingError, match="no usable gyroscope"):
        SessionFit(gyro="on").run(recording)
