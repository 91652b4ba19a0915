"""``<stem>.diagnosis.json`` — the closed loop's report (CONTRACT: "Closed loop").

Keys: ``base`` (residual, parameters), ``steps`` (effect, statistic, dof,
p_value, residual, parameters after the step), ``not_identifiable``, ``final``
(effects, residual, parameters), plus additive extras: every candidate's test
per step, the base model's bias in σ units, residual harmonics of the wheel
angle before and after, and the significance level.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from wheelcal.calibration.session_json import _num, _vec, effects_dict
from wheelcal.closedloop import Diagnosis
from wheelcal.io import MARK_KEY, atomic_write_text, origin_of, output_mark

FORMAT = "wheelcal.diagnosis/1"


def _parameters(result) -> dict:
    return {
        n: {"value": _num(v), "std": _num(s)}
        for n, v, s in zip(result.names, result.values, result.std, strict=True)
    }


def diagnosis_dict(diagnosis: Diagnosis) -> dict:
    """The contract dictionary of a closed-loop diagnosis."""
    base, final = diagnosis.base, diagnosis.final
    return {
        "format": FORMAT,
        MARK_KEY: output_mark(origin_of([base.source]), [base.source]),
        "source": {
            "file": base.source,
            "topic": base.topic,
            "samples": int(base.time_s.size),
            "window_s": list(base.window_s),
            "sensor_id": base.info.sensor_id,
            "mounting_id": base.info.mounting_id,
        },
        "alpha": diagnosis.alpha,
        "correction": "Bonferroni over the candidates of each step (each τ grid point counts)",
        "base": {
            "residual_rms_mps2": _vec(base.residual_rms_mps2),
            "noise_std_mps2": _vec(base.noise.marginal_std_mps2),
            "parameters": _parameters(base),
            "harmonics": diagnosis.harmonics("base"),
        },
        "steps": [
            {
                "effect": step.test.effect.name,
                "label": step.test.effect.label(),
                "description": step.test.effect.description,
                "statistic": _num(step.test.statistic),
                "dof": step.test.dof,
                "p_value": _num(step.test.p_value),
                "p_corrected": _num(step.test.p_corrected),
                "residual_rms_mps2": _vec(step.result.residual_rms_mps2),
                "parameters": _parameters(step.result),
                "tests": [t.as_dict() for t in step.tests],
            }
            for step in diagnosis.steps
        ],
        "not_identifiable": [
            {
                "effect": t.effect.name,
                "label": t.effect.label(),
                "information_fraction": t.information_fraction,
                "reason": "the recording's own parameters can mimic it (singular information)",
            }
            for t in diagnosis.not_identifiable
        ],
        "final": {
            "effects": effects_dict(final),
            "residual_rms_mps2": _vec(final.residual_rms_mps2),
            "noise_std_mps2": _vec(final.noise.marginal_std_mps2),
            "parameters": _parameters(final),
            "harmonics": diagnosis.harmonics("final"),
            "tests": [t.as_dict() for t in diagnosis.final_tests],
        },
        "base_bias_sigma": {k: _num(v) for k, v in diagnosis.base_bias_sigma().items()},
    }


def write_diagnosis(path: str | os.PathLike, diagnosis: Diagnosis, durable: bool = True) -> Path:
    """Write the diagnosis JSON atomically (``durable``: see ``atomic_output``)."""
    text = json.dumps(diagnosis_dict(diagnosis), indent=2, allow_nan=False) + "\n"
    atomic_write_text(path, text, durable=durable)
    return Path(path)
