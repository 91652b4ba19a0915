"""ω(t) as measured, to set beside the model's ω(t) in the session ``.rrd``.

The fitted ω(t) (eq. 2) is a model; a person judging it wants the wheel's rate
measured without that model.  Three sources, best first:

* **gyro, calibrated** — the recording has a gyroscope and the calibration
  holds its scale, axis and bias (:class:`~wheelcal.estimate.gyro.block.GyroCalibration`):
  ω = (ω_meas − b)·w/|w|², w = k·u;
* **gyro, uncalibrated** — a gyroscope but no gyro block: the reading
  projected on its principal direction over the window (the wheel axis, the
  one axis a spinning wheel excites), signed as the model's spin; its scale
  error (≈ 1–3 % for a MEMS gyro) shows as a constant ratio;
* **per turn, from the accelerometer** — no gyroscope: gravity turns once
  per revolution in every axis of the sensor, so the time between two rising
  zero crossings of the most strongly turning axis (with its slow part — the
  offset and the centripetal ω²r — taken out by a moving mean over about one
  turn) is one revolution: ω = 2π / period, at the middle of the turn.  The
  magnitude is measured; the sign is the model's (a zero crossing has none),
  and so is the length of the moving mean (the model's median period: it only
  sets how much is smoothed, never where a crossing lies).

Display only: nothing here feeds the calibration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Turns whose period differs from the median of its neighbours by more than
#: this fraction are dropped (a crossing lost in noise or clipping doubles a period).
_PERIOD_TOLERANCE = 0.25


@dataclass(frozen=True)
class MeasuredRate:
    """ω measured at some times, with what measured it."""

    time_s: np.ndarray
    omega_radps: np.ndarray
    #: "gyro", "gyro (uncalibrated)" or "per turn (accelerometer)"
    source: str


def gyro_rate(
    time_s: np.ndarray, gyro_radps: np.ndarray, calibration, model_sign: float
) -> MeasuredRate | None:
    """ω from gyro rows (N, 3): calibrated when ``calibration`` is given, else principal axis.

    Parameters
    ----------
    time_s:
        Times of the rows, s.
    gyro_radps:
        Gyro readings (N, 3), rad/s; non-finite rows are skipped.
    calibration:
        A :class:`~wheelcal.estimate.gyro.block.GyroCalibration` or ``None``.
    model_sign:
        Sign of the model's ω (orients the principal axis when uncalibrated).
    """
    rows = np.asarray(gyro_radps, dtype=float)
    ok = np.all(np.isfinite(rows), axis=1)
    if ok.sum() < 2:
        return None
    t, rows = np.asarray(time_s, dtype=float)[ok], rows[ok]
    if calibration is not None:
        w = calibration.scale * np.asarray(calibration.axis, dtype=float)
        omega = (rows - calibration.bias_radps) @ w / (w @ w)
        return MeasuredRate(t, omega, "gyro")
    # The wheel axis is the direction of the largest second moment (not centred:
    # a spin of one sign has its rate in the mean, not in the spread).
    _, _, vt = np.linalg.svd(rows, full_matrices=False)
    omega = rows @ vt[0]
    if np.sign(np.median(omega)) != np.sign(model_sign):
        omega = -omega
    return MeasuredRate(t, omega, "gyro (uncalibrated)")


def per_turn_rate(
    time_s: np.ndarray, accel_mps2: np.ndarray, model_omega_radps: np.ndarray
) -> MeasuredRate | None:
    """ω per revolution from the accelerometer alone (module docstring); None if < 3 turns.

    Parameters
    ----------
    time_s:
        Sample times (N,), s, increasing (the free-spin window).
    accel_mps2:
        Samples (N, 3), m/s².
    model_omega_radps:
        The model's ω over the window (any sampling): its median sets the
        moving mean's length, its sign the sign of the result.
    """
    t = np.asarray(time_s, dtype=float)
    a = np.asarray(accel_mps2, dtype=float)
    typical = float(np.median(np.asarray(model_omega_radps, dtype=float)))
    if t.size < 16 or not np.isfinite(typical) or typical == 0.0:
        return None
    dt = (t[-1] - t[0]) / (t.size - 1)
    period_s = 2 * np.pi / abs(typical)
    if not period_s < 0.25 * (t[-1] - t[0]):
        return None  # fewer than four turns
    n = max(3, round(period_s / dt))
    # The axis gravity turns in most: the largest sample-to-sample change (the slow
    # centripetal part hardly changes from one sample to the next).
    # (A few thousand samples decide it: dozens of turns.)
    head = a[: 16 * n]
    k = int(np.argmax(np.sum(np.diff(head, axis=0) ** 2, axis=0)))
    s = a[:, k] - _moving_mean(a[:, k], n)
    rising = np.flatnonzero((s[:-1] < 0) & (s[1:] >= 0))
    rising = rising[(rising >= n // 2) & (rising < s.size - n // 2 - 1)]  # moving mean complete
    if rising.size < 4:
        return None
    # Linear interpolation of each crossing between its two samples.
    frac = -s[rising] / (s[rising + 1] - s[rising])
    crossings = t[rising] + frac * (t[rising + 1] - t[rising])
    # Noise makes a few false crossings near a true one: keep crossings at least
    # half a period apart.
    keep = [0]
    for i in range(1, crossings.size):
        if crossings[i] - crossings[keep[-1]] > 0.5 * period_s:
            keep.append(i)
    crossings = crossings[keep]
    periods = np.diff(crossings)
    if periods.size < 3:
        return None
    reference = _running_median(periods, 5)
    good = np.abs(periods - reference) <= _PERIOD_TOLERANCE * reference
    mid = 0.5 * (crossings[1:] + crossings[:-1])
    omega = np.sign(typical) * 2 * np.pi / periods
    return MeasuredRate(mid[good], omega[good], "per turn (accelerometer)")


def _moving_mean(x: np.ndarray, n: int) -> np.ndarray:
    """Centred moving mean of ``n`` samples (the end values repeated beyond the ends)."""
    padded = np.pad(x, (n // 2, n - n // 2), mode="edge")
    c = np.cumsum(padded)
    return (c[n:] - c[:-n]) / n


def _running_median(x: np.ndarray, n: int) -> np.ndarray:
    """Median of each value's ``n`` neighbours (``n`` odd; the end values repeated)."""
    half = n // 2
    padded = np.pad(x, half, mode="edge")
    return np.median(np.lib.stride_tricks.sliding_window_view(padded, n), axis=1)
