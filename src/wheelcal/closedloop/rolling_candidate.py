"""The rolling wheel as a closed-loop candidate: found from the residual when not declared.

A recording of a wheel that rolls on the ground (a robot's, a car's) fitted as
if the wheel turned on a fixed bench leaves the hub's accelerations in the
residual: ρ ω̇ in the wheel plane, ρ ω ψ̇ and the once-per-turn 2 r ω ψ̇ cos ϑ
along the axle (:mod:`wheelcal.model.rolling`).  With a gyro in the fit the
yaw rate ψ̇ can be demodulated from the gyro at the base fit
(:mod:`wheelcal.estimate.gyro.yaw`), and the effect — ρ, the yaw scale κ and zero ε,
all zero = absent — is score-tested like any other.  Offered only when the fit
used the gyro and the wheel is within :data:`MAX_TILT_FROM_VERTICAL_DEG` of
vertical (a rolling wheel on level ground is vertical; the model assumes it).
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.gyro import demodulate_yaw
from wheelcal.estimate.joint import CalibrationResult
from wheelcal.model import Rolling
from wheelcal.recording import Recording

MAX_TILT_FROM_VERTICAL_DEG = 15.0


def rolling_candidates(fit: CalibrationResult, recording: Recording) -> tuple[Rolling, ...]:
    """The rolling effect for this fit, if it used the gyro and the wheel is vertical."""
    layout = fit.layout
    if not any(e.stage == "gyro" for e in layout.effects) or "rolling" in {
        e.name for e in layout.effects
    }:
        return ()
    if abs(np.rad2deg(fit.params.bench.tilt_rad) - 90.0) > MAX_TILT_FROM_VERTICAL_DEG:
        return ()
    gyro = getattr(recording, "gyro_radps", None)
    if gyro is None:
        return ()
    tc = recording.time_s - fit.centre_s
    return (demodulate_yaw(fit.params, layout, tc, gyro).effect(tc),)
