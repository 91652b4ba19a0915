"""A simulated sensor temperature: self-heating after power-on, with read noise.

    T(t) = T₀ + ΔT · (1 − e^{−t/τ}) + n,   t from the first sample,

the warm-up a MEMS part shows in its first minutes (the same shape as the
accelerometer offset warm-up the closed loop can find).  ``resolution_c``
rounds to the sensor's step (MPU-9250: 1/333.87 °C).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TemperatureSpec:
    """Self-heating from ``start_c`` by ``rise_c`` with time constant ``tau_s``, plus noise."""

    start_c: float = 24.0
    rise_c: float = 3.0
    tau_s: float = 60.0
    noise_c: float = 0.02
    resolution_c: float | None = None

    def __post_init__(self) -> None:
        if not (self.tau_s > 0 and self.noise_c >= 0):
            raise ValueError("tau_s must be positive and noise_c >= 0")
        if self.resolution_c is not None and not self.resolution_c > 0:
            raise ValueError("resolution_c must be positive (or None)")

    def clean(self, time_s: np.ndarray) -> np.ndarray:
        """T(t) without noise, t from the first sample."""
        t = np.asarray(time_s, dtype=float)
        return self.start_c + self.rise_c * -np.expm1(-(t - t[0]) / self.tau_s)

    def sample(self, time_s: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """T(t) with noise (one normal draw per sample, if noisy) and rounding."""
        temp = self.clean(time_s)
        if self.noise_c > 0:
            temp = temp + self.noise_c * rng.standard_normal(temp.shape)
        if self.resolution_c is not None:
            temp = np.round(temp / self.resolution_c) * self.resolution_c
        return temp
