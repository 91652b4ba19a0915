"""What a road does to a wheel besides its turns: a camber that changes, and a shaking carrier.

Learnt from measured car drives (wheel-mounted Xsens DOTs on a car's four wheels,
2-minute drives at 4–8 m/s; the guide's "Wheels in the field" compares the
statistics):

* **The camber follows the road.**  The gyro reads each wheel rolling about its
  direction of travel by 4–6.5° over a drive, the two sensors on one wheel alike —
  the road's cross-slope and crown changing along it, banked curves, a steered
  wheel's caster.  Here the camber is γ(t) = γ₀ + c(s(t)) + caster: c a smooth
  random function of the distance s travelled (a Gaussian process with a squared-
  exponential correlation of length ``cross_slope_length_m``, as a sum of random
  Fourier modes, so its derivatives are exact), and for a steered wheel −σ δ sin τ
  (τ the caster, δ = atan(L ψ̇ / v) the steering angle of a kinematic bicycle of
  wheelbase L; σ the side: both wheels lean into the turn).
* **The carrier shakes in rotation, not only in translation.**  Above 2 Hz the
  measured gyro reads 0.02–0.05 rad/s rms about each of the carrier's axes (the
  knuckle's pitch about the axle — the tyre's torsional spring — most), roughly
  white to 60 Hz: a real rotation, which the accelerometer sees through its lever
  (r ν̇ along the tangent: ~1 m/s² at 40 Hz on a rim).  Here the carrier turns by
  ν(t) = (ν_yaw e_z + ν_roll σ f + ν_pitch Z) besides its yaw and roll, each band-
  limited white noise (``shake_band_hz``) of rms ``shake_rates_radps`` at full speed,
  its envelope following the speed as the road's vibration does
  (:class:`~wheelcal.simulate.road.VibrationSpec`).  The attitude it leaves (≲ 0.03°)
  is below what anything resolves and is not integrated.

The profile's random series come from its own ``seed`` (drawn with the scenario), so
a scenario with a road draws the rest of its recording exactly as one without.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.simulate.field_motion import MotionState
from wheelcal.simulate.road import VibrationSpec

#: Random Fourier modes of the road's cross-slope.
MODES = 48


@dataclass(frozen=True)
class RoadProfile:
    """A road's camber and the carrier's angular shaking (module docstring).

    Parameters
    ----------
    cross_slope_std_deg, cross_slope_length_m:
        The camber's change along the road: std and correlation length.
    caster_deg:
        A steered wheel's caster (0: not steered); ``wheelbase_m`` L of its bicycle.
    shake_rates_radps:
        rms of the carrier's angular vibration (yaw, roll, pitch about the axle) at full
        speed, rad/s; ``shake_band_hz`` its band; ``full_speed_mps`` where the envelope
        reaches 1 (∝ √v below, as the road's translation).
    seed:
        The profile's own random series.
    """

    cross_slope_std_deg: float = 1.5
    cross_slope_length_m: float = 60.0
    caster_deg: float = 0.0
    wheelbase_m: float = 2.5
    shake_rates_radps: tuple[float, float, float] = (0.03, 0.025, 0.05)
    shake_band_hz: tuple[float, float] = (2.0, 55.0)
    full_speed_mps: float = 8.0
    seed: int = 0

    def __post_init__(self) -> None:
        values = (self.cross_slope_std_deg, self.caster_deg, *self.shake_rates_radps)
        if not all(np.isfinite(v) and v >= 0 for v in values):
            raise ValueError("the road's std, caster and shake rates must be finite and >= 0")
        if not (self.cross_slope_length_m > 0 and self.wheelbase_m > 0 and self.full_speed_mps > 0):
            raise ValueError("cross_slope_length_m, wheelbase_m and full_speed_mps must be > 0")
        low, high = self.shake_band_hz
        if not 0 < low < high:
            raise ValueError(
                f"shake_band_hz must be (low, high), 0 < low < high: {self.shake_band_hz}"
            )

    @classmethod
    def car(cls, rng: np.random.Generator, steered: bool | None = None) -> RoadProfile:
        """A car's road as the measured drives show it (a steered wheel half the time)."""
        steered = bool(rng.uniform() < 0.5) if steered is None else steered
        shake = tuple(float(x) for x in rng.uniform(0.5, 1.5) * np.array([0.03, 0.025, 0.05]))
        return cls(
            cross_slope_std_deg=float(rng.uniform(0.8, 2.0)),
            cross_slope_length_m=float(rng.uniform(30.0, 120.0)),
            caster_deg=float(rng.uniform(3.0, 7.0)) if steered else 0.0,
            shake_rates_radps=shake,
            seed=int(rng.integers(2**31)),
        )

    def camber_change(self, state: MotionState, side: int, t: np.ndarray) -> np.ndarray:
        """c(s(t)) − σ δ(t) sin τ: the camber's change from the road and the steering (rad)."""
        rng = np.random.default_rng(self.seed)
        k = rng.standard_normal(MODES) / self.cross_slope_length_m
        phase = rng.uniform(-np.pi, np.pi, MODES)
        amplitude = np.deg2rad(self.cross_slope_std_deg) * np.sqrt(2.0 / MODES)
        s = np.asarray(state.distance_m, dtype=float)
        road = amplitude * np.cos(np.outer(s, k) + phase).sum(axis=1)
        road -= road[0]  # the static camber is the wheel's own at the start
        if self.caster_deg == 0.0:
            return road
        v = np.maximum(np.asarray(state.speed_mps, dtype=float), 0.5)  # a crawl: no steering
        steer = np.arctan(self.wheelbase_m * np.asarray(state.yaw_rate_radps) / v)
        steer = np.clip(steer, -np.deg2rad(35.0), np.deg2rad(35.0))
        return road - side * steer * np.sin(np.deg2rad(self.caster_deg))

    def shake(self, state: MotionState, rate_hz: float, n: int) -> np.ndarray:
        """(n, 3): ν_yaw, ν_roll, ν_pitch (rad/s), the carrier's angular vibration."""
        rng = np.random.default_rng(self.seed + 1)
        yaw, roll, pitch = self.shake_rates_radps
        top = max(yaw, roll, pitch)
        if top == 0.0:
            return np.zeros((n, 3))
        spec = VibrationSpec(
            top,
            band_hz=self.shake_band_hz,
            axis_ratio=(yaw / top, roll / top, pitch / top),
            full_speed_mps=self.full_speed_mps,
        )
        return spec.sample(n, rate_hz, rng) * spec.envelope(state.speed_mps)[:, None]
