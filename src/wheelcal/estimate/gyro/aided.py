"""The gyro-aided joint fit's set-up, and the gyroscope's block from a fit.

What a fit with the gyroscope needs is the estimator's to decide, behind its
front; a session (:mod:`wheelcal.session.fit`) only sequences the steps:

* :func:`gyro_aided`: the joint fit configured for a window with the gyro — the
  gyro's rows, a spline wheel angle whose knot spacing is chosen by BIC on the
  gyro's rate (:func:`~wheelcal.estimate.gyro.knots.choose_knot_spacing`), and the
  gyro's readings at the rests;
* :func:`fastest_rate_radps`: the wheel's fastest rate as the fitted gyro axis reads it;
* :func:`gyro_rows` and :func:`gyro_block`: the gyroscope's calibration from a fit —
  the fit's own gyro block when it fitted the gyro, else a regression on its ω(t).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.gyro.block import GyroCalibration, gyro_by_product, gyro_from_fit
from wheelcal.estimate.gyro.knots import choose_knot_spacing
from wheelcal.estimate.joint import CalibrationResult, JointFit, gyro_effect, gyro_samples
from wheelcal.model import GyroReading
from wheelcal.recording import Recording


@dataclass(frozen=True, eq=False)
class GyroAided:
    """A joint fit configured for a window with the gyro, and what it was configured from."""

    fitter: JointFit
    #: The spline's knot spacing, chosen by BIC on the gyro's rate (s).
    knot_spacing_s: float
    #: The window's usable gyro rows (rad/s), in the window's centred time.
    gyro_radps: np.ndarray


def gyro_aided(fitter: JointFit, window: Recording, rests) -> GyroAided:
    """``fitter`` set up for the gyro-aided fit of ``window`` (module docstring).

    ``rests`` are the recording's :class:`~wheelcal.estimate.rests.RestSegment`
    around the window (the gyro's readings there join the fit).
    """
    tc = window.time_s - 0.5 * (window.time_s[0] + window.time_s[-1])
    gyro_t, gyro = gyro_samples(window, tc)
    knots = choose_knot_spacing(gyro_t, gyro)
    aided = dataclasses.replace(
        fitter,
        use_gyro=True,
        spline_spacing_s=knots.spacing_s,
        gyro_rests=fitter.rests_of(rests),
    )
    return GyroAided(aided, knots.spacing_s, gyro)


def fastest_rate_radps(result: CalibrationResult, gyro_radps: np.ndarray) -> float:
    """The largest |ω| the gyro rows show along the fitted gyro axis (its gain divided out)."""
    axis = result.params.effect("gyro", 6)[:3]
    fastest = float(np.max(np.abs(gyro_radps @ axis)))
    return fastest / max(float(np.sum(axis**2)), 1e-12)


def gyro_rows(result: CalibrationResult, window: Recording) -> tuple[np.ndarray, np.ndarray]:
    """The usable gyro rows of ``window`` in ``result``'s centred time (times, rad/s)."""
    return gyro_samples(window, window.time_s - result.centre_s)


def gyro_block(
    result: CalibrationResult,
    rows: tuple[np.ndarray, np.ndarray],
    reading: GyroReading | None = None,
) -> GyroCalibration:
    """The gyroscope's calibration from ``result`` and the gyro ``rows`` (:func:`gyro_rows`).

    The fit's own gyro block when it (or the closed loop) fitted the gyro; else a
    regression on its ω(t), with ``reading`` the gyro's reading.
    """
    gyro_t, gyro = rows
    if gyro_effect(result.layout) is not None:
        return gyro_from_fit(result, gyro_t, gyro)
    return gyro_by_product(result, gyro_t, gyro, reading=reading)
