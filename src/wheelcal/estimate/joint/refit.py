"""Refits of a joint fit without the samples the model cannot explain.

Two reasons to leave samples out and fit again, each judged from the fit
itself: a disturbance (a hand starting or braking the wheel, a knock: the
residual's RMS far above the typical, :func:`without_disturbances`), and a
clipping rail (the model puts the sample near a rail, :func:`clear_of_rails`).
Each refit restarts from the fit's parameters in the window's own time frame,
and returns the refit, the samples kept and a note for the session's reason
(empty when nothing was left out).
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.joint.fit import JointFit
from wheelcal.estimate.joint.result import CalibrationResult
from wheelcal.recording import Recording

#: Stretches of the motion window whose residual exceeds this × the typical are left out.
DISTURBANCE_FACTOR = 2.0
DISTURBANCE_BLOCK_S = 0.5


def without_disturbances(
    fitter: JointFit, result: CalibrationResult, window: Recording
) -> tuple[CalibrationResult, Recording, str]:
    """Refit without the stretches where something outside the model shook the sensor.

    A gyro-aided window follows the whole motion, and a motion can include a
    hand starting or braking the wheel, whose forces are not in the model.  The
    residual shows them: blocks of ``DISTURBANCE_BLOCK_S`` whose RMS exceeds
    ``DISTURBANCE_FACTOR`` × the median block are left out (with a block on
    each side), and the fit is repeated once.
    """
    n = max(4, round(DISTURBANCE_BLOCK_S * window.rate_hz))
    samples = result.residual_mps2.shape[0]
    block = np.arange(samples) // n  # the last block may be partial: it is judged too
    if block[-1] < 8:
        return result, window, ""
    power = np.bincount(block, weights=np.sum(result.residual_mps2**2, axis=1))
    rms = np.sqrt(power / (3 * np.bincount(block)))
    bad = rms > DISTURBANCE_FACTOR * np.median(rms)
    if not np.any(bad):
        return result, window, ""
    bad = bad | np.concatenate([[False], bad[:-1]]) | np.concatenate([bad[1:], [False]])
    keep = ~bad[block]
    kept = window.select(keep)
    # The refit keeps the window's time origin and knots: it restarts where it was.
    frame = (float(window.time_s[0]), float(window.time_s[-1]))
    refit = fitter.fit(kept, initial=result.params, frame=frame)
    seconds = float(np.sum(~keep) / window.rate_hz)
    note = (
        f"left out {seconds:.1f} s where the residual exceeded {DISTURBANCE_FACTOR:g}× the "
        "typical (a hand starting or braking the wheel, a knock)"
    )
    return refit, kept, note


#: Samples the model puts within this many noise σ of a rail are left out.
RAIL_MARGIN_SIGMA = 4.0


def clear_of_rails(
    fitter: JointFit, result: CalibrationResult, window: Recording
) -> tuple[CalibrationResult, Recording, str]:
    """Refit without the stretches the model predicts near a clipping rail.

    The reader dropped the samples at the rails; keeping their neighbours
    whose noise stayed just below would select on the noise and bias the
    peaks.  Selecting on the *prediction* instead is free of that bias.
    """
    predicted = window.accel_mps2 - result.residual_mps2
    margin = RAIL_MARGIN_SIGMA * result.noise.marginal_std_mps2
    low, high = window.clip_limits_mps2[:, 0], window.clip_limits_mps2[:, 1]
    with np.errstate(invalid="ignore"):
        near = np.any((predicted >= high - margin) | (predicted <= low + margin), axis=1)
    if not np.any(near):
        return result, window, ""
    kept = window.select(~near)
    frame = (float(window.time_s[0]), float(window.time_s[-1]))  # see without_disturbances
    refit = fitter.fit(kept, initial=result.params, frame=frame)
    note = (
        f"left out {int(near.sum())} samples that the model puts within "
        f"{RAIL_MARGIN_SIGMA:g} σ of a clipping rail"
    )
    return refit, kept, note
