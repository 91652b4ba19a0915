"""The yaw rate of a rolling wheel, from its gyroscope (geometry ``rolling``).

A wheel that rolls and turns has the angular velocity Ω = −ω e_Z + ψ̇ u
(:mod:`wheelcal.model.rolling`; u = (cos ϑ, sin ϑ, 0) the upward direction in
the bench frame).  The gyro's model of the spin (:class:`GyroReading`:
w ω + b + G a) explains the first part; what is left turns with the wheel:

    ψ̇_raw(t) = (R u(ϑ))ᵀ (ω_meas − w ω − b − G a)             (demodulation)

then a zero-phase low-pass at ``band_hz`` (a vehicle's yaw changes within
seconds; the wheel turns many times a second) gives ψ̇_gyro(t).  Its scale is
the gyro's mean scale across the axle, which the spin does not calibrate: the
rolling effect fits κ and a zero ε in ψ̇ = κ ψ̇_gyro + ε.  The yaw's share of
the gyro samples, ψ̇_gyro (cos ϑ h_X + sin ϑ h_Y), with h_X, h_Y (the gyro's
response to rates along the bench X and Y, its scale errors and misalignment
included) by least squares, is taken out of the gyro stream before the joint
fit, whose gyro model knows the spin only.

b and G are refitted together with h, and the demodulation repeated with them
(``_ITERATIONS`` rounds, a fixed point): the fit that gives ϑ and w saw the
yaw as noise, and G_X a_X = G_X (r ω² + g cos ϑ) shares cos ϑ with the yaw's
cos ϑ h_X — a steady yaw and the gyro's sensitivity to gravity turn alike,
which is why ε is left to the accelerometer.

The accelerometer's ϑ and R enter through u; an error δ in the direction of
R u changes ψ̇_raw by a factor cos δ, and its leak across is part of h.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint.gyro_equations import gyro_effect
from wheelcal.model import (
    CalibrationParams,
    ParameterLayout,
    Rolling,
    bench_force,
    wheel_kinematics,
)

#: Low-pass corner of the demodulated yaw rate (Hz).
YAW_BAND_HZ = 2.0
#: Rounds of (demodulate, regress the gyro's steady terms and its yaw response).
_ITERATIONS = 30


@dataclass(frozen=True, eq=False)
class YawEstimate:
    """ψ̇_gyro at every sample (N,), and its share of the gyro samples (N, 3)."""

    yaw_rate_radps: np.ndarray
    gyro_share_radps: np.ndarray
    response_radps: np.ndarray  # (2, 3): h_X, h_Y

    def effect(self, time_centred_s: np.ndarray) -> Rolling:
        """The rolling effect with this yaw (times: the recording's, centred)."""
        return Rolling(time_centred_s, self.yaw_rate_radps, gyro_yaw_radps=self.gyro_share_radps)


def demodulate_yaw(
    params: CalibrationParams,
    layout: ParameterLayout,
    time_centred_s: np.ndarray,
    gyro_radps: np.ndarray,
    band_hz: float = YAW_BAND_HZ,
) -> YawEstimate:
    """ψ̇_gyro(t) and the yaw's share of the gyro from a fit's parameters (module doc).

    ``layout`` holds the fit's gyro reading and wheel-angle spline;
    ``gyro_radps`` has one row per time (rows with non-finite values are
    bridged by interpolation).
    """
    from scipy import signal

    t = np.asarray(time_centred_s, dtype=float)
    gyro = np.asarray(gyro_radps, dtype=float)
    valid = np.all(np.isfinite(gyro), axis=1)
    reading = gyro_effect(layout)
    values = params.effect(reading.name, reading.size)
    kin = wheel_kinematics(params, t, layout.effects)
    s, c = np.sin(kin.theta_rad), np.cos(kin.theta_rad)
    up = np.column_stack([c, s, np.zeros_like(c)]) @ params.bench.misalignment.matrix.T
    rest = gyro - np.outer(kin.omega_radps, values[:3])  # the spin's share w ω is known well
    columns = [np.ones_like(t)]
    if reading.g_sensitivity:
        bench = params.bench
        force = bench_force(kin, bench.tilt_rad, bench.radius_m, params.gravity_mps2).accel_mps2
        columns += [force[:, 0], force[:, 1]]
    steady = np.column_stack(columns)  # b, G_X, G_Y: (k, 3) coefficients
    coef = values[3:].reshape(-1, 3)
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    grid = np.linspace(t[0], t[-1], round((t[-1] - t[0]) * rate_hz) + 1)  # gaps bridged
    sos = signal.butter(4, min(band_hz, 0.4 * rate_hz), fs=rate_hz, output="sos")
    # b and G are refitted with the yaw's share: the first fit saw the yaw as noise, and
    # G_X a_X = G_X (r ω² + g cos ϑ) shares cos ϑ with the yaw's cos ϑ h_X.
    for _ in range(_ITERATIONS):
        raw = np.sum((rest - steady @ coef) * up, axis=1)
        yaw = np.interp(t, grid, signal.sosfiltfilt(sos, np.interp(grid, t[valid], raw[valid])))
        turning = np.column_stack([yaw * c, yaw * s])
        design = np.hstack([steady, turning])
        solution, *_ = np.linalg.lstsq(design[valid], rest[valid], rcond=None)
        coef, response = solution[: steady.shape[1]], solution[steady.shape[1] :]
    return YawEstimate(yaw, turning @ response, response)
