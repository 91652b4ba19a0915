"""The fitted wheel angle ϑ(t) at every sample of a fit, in cache-sized chunks."""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.joint.normal_equations import CHUNK_SAMPLES
from wheelcal.estimate.joint.result import CalibrationResult
from wheelcal.model import EvaluatedModel, wheel_kinematics


def wheel_angle_rad(
    result: CalibrationResult, evaluated: EvaluatedModel | None = None
) -> np.ndarray:
    """The fitted wheel angle ϑ(t) at every sample of ``result`` (the kinematics only).

    ``evaluated``: the model at the result as the fit's last pass left it, whose ϑ
    serves when it has it; else ϑ is computed in chunks of :data:`CHUNK_SAMPLES`.
    """
    tc = result.centred_time_s
    output = evaluated.output_at(result.params, tc) if evaluated is not None else None
    if output is not None:
        return output.kinematics.theta_rad
    theta = np.empty_like(tc)
    for start in range(0, tc.size, CHUNK_SAMPLES):
        stop = min(tc.size, start + CHUNK_SAMPLES)
        kin = wheel_kinematics(result.params, tc[start:stop], result.layout.effects)
        theta[start:stop] = kin.theta_rad
    return theta
