"""The estimators, in subsystems: the joint ML fit, the paper's four steps, the gyroscope.

Layer 3 (above ``recording``, beside ``io`` and ``simulate``; below ``closedloop``).

* :mod:`.joint` — the joint maximum-likelihood fit: its start, normal equations,
  Levenberg–Marquardt, noise model, the Fisher information by quadrature, the
  Cramér–Rao bound, identifiability, twins, the systematic budget, the frozen result;
* :mod:`.paper` — the paper's four-step estimator (III-A … D), for comparison;
* :mod:`.gyro` — the gyroscope's calibration and the gyro-aided fit's set-up;
* :mod:`.field` — a wheel in the field, the one model of a rolling wheel;
* the rests of a recording (:mod:`.rests`) and their Allan deviation (:mod:`.allan`),
  and the residual by wheel angle (:mod:`.residual_profile`).

Subsystems import ``joint``, never the reverse.
"""

from wheelcal.estimate.allan import WHITE_NOISE_TAU_S, AllanDeviation, AllanSums
from wheelcal.estimate.residual_profile import residual_by_wheel_angle
from wheelcal.estimate.rests import RestSegment, find_rests, pooled_noise_std

__all__ = [
    "WHITE_NOISE_TAU_S",
    "AllanDeviation",
    "AllanSums",
    "RestSegment",
    "find_rests",
    "pooled_noise_std",
    "residual_by_wheel_angle",
]
