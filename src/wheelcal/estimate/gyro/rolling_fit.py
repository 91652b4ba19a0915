"""The joint fit of a rolling wheel (geometry ``rolling``): yaw from the gyro, then ρ and κ.

The rolling effect (:mod:`wheelcal.model.rolling`) needs the yaw rate ψ̇(t),
which the gyro measures but only once ϑ(t), R and the gyro's spin model are
known (:mod:`wheelcal.estimate.gyro.yaw`).  So:

1. a first pass with the hub's travel ρ ω̇ only (κ held at 1, no yaw yet) — the
   turns' forces are left in the residual, but ϑ(t), R and the gyro's spin
   model are close;
2. demodulate ψ̇_gyro with that fit, take the yaw's share out of the gyro
   stream, fit everything with ρ and κ free;
3. repeat 2 with the better fit (``ROLLING_PASSES`` in all).

A fit started from given parameters (a refit of a subset) skips 1.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wheelcal.estimate.gyro.yaw import demodulate_yaw
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.estimate.joint.initial import InitialGuess
from wheelcal.estimate.joint.result import CalibrationResult
from wheelcal.model import CalibrationParams, Rolling
from wheelcal.recording import Recording, RecordingError

#: Passes of (demodulate the yaw with the latest fit, refit).
ROLLING_PASSES = 1


def fit_window(
    fitter: JointFit,
    recording: Recording,
    initial: CalibrationParams | None = None,
    guess: InitialGuess | None = None,
    frame: tuple[float, float] | None = None,
) -> CalibrationResult:
    """``fitter.fit(…)``, or the passes of the module doc for a rolling wheel of unknown yaw.

    The joint fit of geometry ``rolling`` needs the rolling effect with its yaw
    series (demodulated from the gyro with a first fit); a refit that carries it
    is a plain joint fit.
    """
    if fitter.geometry == "rolling" and not any(e.stage == "force" for e in fitter.effects):
        return _fit_rolling(fitter, recording, initial, guess, frame)
    return fitter.fit(recording, initial=initial, guess=guess, frame=frame)


def _fit_rolling(
    fitter: JointFit,
    recording: Recording,
    initial: CalibrationParams | None,
    guess: InitialGuess | None,
    frame: tuple[float, float] | None,
) -> CalibrationResult:
    """Fit ``recording`` in geometry ``rolling`` with ``fitter``'s other settings (module doc)."""
    t = recording.time_s
    frame = frame or (float(t[0]), float(t[-1]))
    tc = t - 0.5 * (frame[0] + frame[1])
    gyro = getattr(recording, "gyro_radps", None)
    if gyro is None:
        raise RecordingError(f"{recording.source}: geometry 'rolling' needs the gyroscope")
    notes: list[str] = []
    if initial is None:
        travel = Rolling(tc, np.zeros_like(tc), yaw_scale_free=False)
        first = dataclasses.replace(fitter, effects=(*fitter.effects, travel))
        guess = guess or first.start(recording)
        notes += guess.notes
        start = guess.params.with_changes(effects={**guess.params.effects, travel.name: [0.0]})
        initial = first.fit(recording, initial=start, frame=frame).params
    layout = fitter.layout_for(recording, frame)
    result = None
    for _ in range(ROLLING_PASSES):
        yaw = demodulate_yaw(initial, layout, tc, gyro)
        effect = yaw.effect(tc)
        values = np.asarray(initial.effects.get(effect.name, [0.0]), dtype=float)
        if values.size != effect.size or values[1] == 0.0:
            values = np.array([values[0], 1.0, 0.0])
        start = initial.with_changes(effects={**initial.effects, effect.name: values})
        result = dataclasses.replace(fitter, effects=(*fitter.effects, effect)).fit(
            recording, initial=start, frame=frame
        )
        initial = result.params
    note = (
        f"rolling wheel: yaw rate from the gyro (RMS {effect.settings()['yaw_rate_rms_radps']:.3g}"
        f" rad/s, max {effect.settings()['yaw_rate_max_radps']:.3g} rad/s), "
        f"{ROLLING_PASSES} passes"
    )
    return dataclasses.replace(result, notes=tuple(notes) + result.notes + (note,))
