"""The field fit's starting point, from the gyro's angle and the accelerometer's gravity.

The gyro gives the wheel angle's shape, Θ(t) = ∫ ω_g dt, but not its origin,
its scale error (≈ 1 %: 18 rad over 1800 rad of a drive) or the drift of its
bias.  Gravity, turning in the wheel's plane, gives the rest:

1. the plane: the accelerometer's samples projected on two directions across
   the gyro's axle (the two sensors share a chip), as z(t) = x + i y;
2. its turning part (less what varies slower than ``PHASE_BAND_HZ``: a car
   wheel's r ω², tens of g, stands still in the sensor's frame), demodulated by
   the gyro's angle, z e^{∓iΘ}, keeps only what Θ misses — a slowly turning
   phase φ(t) — once low-passed (the wheel's own rotation is gone, a push or a
   reversal too); the sign whose demodulation keeps more power is the wheel's
   direction in this frame; φ is summed from its increments between the samples
   where gravity is seen turning, so a stop cannot slip it by a turn, and the
   gyro's bias, which turns Θ during a stop, is counted across it;
3. ϑ(t) = ±Θ + φ(t) ≈ ϑ₀ + ω₀ t + s Θ by least squares (the gyro's bias and scale);
4. with ϑ known, the accelerometer is linear in what is left (eq. 1 at α = 90°,
   plus the hub's travel ρ ω̇ (sin ϑ, −cos ϑ, 0) of a rolling wheel):
   v = o + A cos ϑ + B sin ϑ + C ω² + D ω̇ + E ω̇ sin ϑ + F ω̇ cos ϑ;
   the centripetal direction C fixes the phase's origin (the bench X), and the
   gains and R follow as in :mod:`wheelcal.estimate.joint.initial`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from wheelcal.estimate.field.gyro_axle import GyroAxle
from wheelcal.estimate.joint import scaled_gains
from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    GyroAngle,
    Rotation,
    SensorParams,
    SpinParams,
)
from wheelcal.recording import RecordingError

#: Low-pass of the demodulated gravity (Hz): the phase error the gyro leaves is slow.
PHASE_BAND_HZ = 0.5


@dataclass(frozen=True, eq=False)
class FieldStart:
    """Starting parameters (spin degree 0 and the gyro angle), the oriented axle, the notes."""

    params: CalibrationParams
    axle: GyroAxle
    angle: GyroAngle
    notes: tuple[str, ...]


def _plane(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors across ``axis``, (e1, e2, axis) right-handed."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    e1 = np.cross(helper, axis)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(axis, e1)


def _slow_phase(t, z, angle, gravity_mps2) -> tuple[int, np.ndarray, np.ndarray]:
    """The wheel's sign in the plane, φ(t) and where it was seen (step 2).

    The slow part of z (a car wheel's r ω² reaches tens of g, and stands still in
    the sensor's frame) is taken out first, so that only the turning gravity is
    demodulated; φ is summed from its increments between the samples where gravity
    was seen turning (|d| above a third of g), so that a stop cannot make it slip a
    turn, while what Θ gained across the stop (the gyro's bias) is kept.
    """
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    band = min(PHASE_BAND_HZ, 0.4 * rate_hz)
    sos = signal.butter(2, band, fs=rate_hz, output="sos")
    turning = z - signal.sosfiltfilt(sos, z)
    best = None
    for sign in (1, -1):
        d = signal.sosfiltfilt(sos, turning * np.exp(-1j * sign * angle))
        power = float(np.mean(np.abs(d) ** 2))
        if best is None or power > best[0]:
            best = (power, sign, d)
    _, sign, d = best
    seen = np.abs(d) > gravity_mps2 / 3
    # from each seen sample to the next one seen: across a stop too, where the gyro's bias
    # turns Θ (~0.01 rad/s) while gravity stands still — summed only where seen, a long
    # drive's stops (a tenth of it) left ω₀ off by that bias's tenth, a radian at ±15 min
    where = np.flatnonzero(seen)
    steps = np.zeros(z.size)
    steps[where[1:]] = np.angle(d[where[1:]] * np.conj(d[where[:-1]]))
    return sign, np.cumsum(steps), seen.astype(float)


def field_start(
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    gravity_mps2: float,
    axle: GyroAxle,
    radius_m: float | None = None,
    walk: dict | None = None,
) -> FieldStart:
    """The starting point of the field fit (module docstring) at centred times ``t_s``.

    ``walk``: the gyro angle's bias walk (:class:`~wheelcal.model.GyroAngle`'s
    ``walk_spacing_s``, ``walk_prior_radps_per_sqrt_s``), started at zero.
    """
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(accel_mps2, dtype=float)
    notes: list[str] = []
    e1, e2 = _plane(axle.axis)
    centred = v - v.mean(axis=0)
    z = centred @ e1 + 1j * (centred @ e2)
    angle = GyroAngle(t, axle.rate_radps, axle.rate_dot_radps2).angle
    sign, phase, weight = _slow_phase(t, z, angle, gravity_mps2)
    if np.count_nonzero(weight) < 10:
        raise RecordingError(
            "the accelerometer never shows gravity turning with the wheel (is the wheel's "
            "axle vertical, or the sensor on another body?)"
        )
    if sign < 0:  # ϑ runs against this end of the axle: see it from the other
        axle, angle = axle.flipped(), -angle
    theta_s = angle + phase
    design = np.column_stack([np.ones_like(t), t, angle]) * np.sqrt(weight)[:, None]
    (theta0, bias, scale), *_ = np.linalg.lstsq(design, theta_s * np.sqrt(weight), rcond=None)
    theta = theta0 + bias * t + scale * angle
    omega = bias + scale * axle.rate_radps
    omega_dot = scale * axle.rate_dot_radps2
    s, c = np.sin(theta), np.cos(theta)
    columns = [np.ones_like(t), c, s, omega**2, omega_dot, omega_dot * s, omega_dot * c]
    coef, *_ = np.linalg.lstsq(np.column_stack(columns), v, rcond=None)
    offset, c_cos, c_sin, centripetal = coef[0], coef[1], coef[2], coef[3]
    # The phase's origin: the centripetal term points along the bench X.
    strength = np.linalg.norm(centripetal) / max(np.linalg.norm(c_cos), 1e-12)
    shift = float(np.arctan2(c_sin @ centripetal, c_cos @ centripetal))
    if strength < 1e-4:
        shift = 0.0
        notes.append("the sensor sits on the axle: the radial direction is not measurable")
    gw_x = c_cos * np.cos(shift) + c_sin * np.sin(shift)
    gw_y = -c_cos * np.sin(shift) + c_sin * np.cos(shift)
    scaled = scaled_gains(gw_x, gw_y)
    if scaled is None:
        notes.append("gain ratios not resolvable from the rotating signal; started from unit gains")
        scaled = np.full(3, 0.5 * (np.linalg.norm(gw_x) + np.linalg.norm(gw_y)))
    gain = np.clip(scaled / gravity_mps2, 0.2, 5.0)
    r_x, r_y = gw_x / scaled, gw_y / scaled
    rot = Rotation.nearest(np.column_stack([r_x, r_y, np.cross(r_x, r_y)]))
    w_x = gain * rot.matrix[:, 0]
    radius = radius_m
    if radius is None:
        radius = float(abs(centripetal @ w_x) / (w_x @ w_x))
    params = CalibrationParams(
        spin=SpinParams(theta0 - shift, [bias]),
        bench=BenchParams(tilt_rad=np.pi / 2, radius_m=radius, misalignment=rot),
        sensor=SensorParams(offset_mps2=offset, gain=gain),
        gravity_mps2=gravity_mps2,
        effects={GyroAngle.name: [scale]},
    )
    oriented = GyroAngle(t, axle.rate_radps, axle.rate_dot_radps2, **(walk or {}))
    if oriented.size > 1:  # the walk's changes start at zero
        walk_start = [scale] + [0.0] * (oriented.size - 1)
        params = params.with_changes(effects={GyroAngle.name: walk_start})
    return FieldStart(params, axle, oriented, tuple(notes))
