"""Sensor noise for the simulator: white, or band-limited by a low-pass filter.

Real MEMS accelerometers filter their output digitally (e.g. the MPU-9250
DLPF), so their noise is coloured.  The band-limited model is white noise
through the all-pole part of a 2nd-order Butterworth low-pass,

    x_n + a₁ x_{n−1} + a₂ x_{n−2} = e_n,

an AR(2) process.  Its exact whitening filter A(z) = 1 + a₁z⁻¹ + a₂z⁻² is
known, so the Cramér–Rao bound for coloured noise can be computed exactly
(:mod:`wheelcal.estimate.joint.crlb`).  ``std_mps2`` is always the *marginal*
standard deviation per sample, the number a datasheet quotes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model import ar_variance_gain


@dataclass(frozen=True)
class NoiseSpec:
    """Gaussian sensor noise per axis.

    Parameters
    ----------
    std_mps2:
        Marginal standard deviation (m/s²), one value or one per axis.
    bandwidth_hz:
        ``None`` for white noise; else the corner of the low-pass filter.
    """

    std_mps2: float | tuple[float, float, float] = 0.08
    bandwidth_hz: float | None = None

    def __post_init__(self) -> None:
        std = np.broadcast_to(np.asarray(self.std_mps2, dtype=float), (3,))
        if np.any(std < 0) or not np.all(np.isfinite(std)):
            raise ValueError(f"noise std must be finite and >= 0, got {self.std_mps2}")
        object.__setattr__(self, "std_mps2", tuple(float(s) for s in std))
        if self.bandwidth_hz is not None and not self.bandwidth_hz > 0:
            raise ValueError("bandwidth_hz must be positive")

    @property
    def std(self) -> np.ndarray:
        """Marginal std per axis, shape (3,)."""
        return np.array(self.std_mps2)

    def ar_polynomial(self, rate_hz: float) -> np.ndarray:
        """Whitening FIR A(z) = [1, a₁, …]; ``[1]`` for white noise."""
        if self.bandwidth_hz is None or self.bandwidth_hz >= 0.45 * rate_hz:
            return np.array([1.0])
        from scipy import signal  # heavy import, only when simulating coloured noise

        _, a = signal.butter(2, self.bandwidth_hz, fs=rate_hz)
        return a / a[0]

    def innovation_std(self, rate_hz: float) -> np.ndarray:
        """Std of the white innovations e_n that give the marginal std."""
        return self.std / np.sqrt(ar_variance_gain(self.ar_polynomial(rate_hz)))

    def sample(self, n: int, rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        """Draw (n, 3) samples of stationary noise."""
        a = self.ar_polynomial(rate_hz)
        e = rng.standard_normal((n, 3)) * self.innovation_std(rate_hz)
        if a.size == 1:
            return e
        # Start in the stationary state: run a burn-in of 20 filter time constants.
        from scipy import signal

        burn = int(20 * rate_hz / (2 * np.pi * self.bandwidth_hz)) + 10
        warm = rng.standard_normal((burn, 3)) * self.innovation_std(rate_hz)
        out = signal.lfilter([1.0], a, np.vstack([warm, e]), axis=0)
        return out[burn:]


@dataclass(frozen=True)
class Quantiser:
    """A digital sensor's output stage: ``bits`` over ±``full_scale_g`` g, with clipping."""

    full_scale_g: float = 4.0
    bits: int = 16
    gravity_mps2: float = 9.80665

    @property
    def lsb_mps2(self) -> float:
        """Size of one count in m/s²."""
        return 2 * self.full_scale_g * self.gravity_mps2 / 2**self.bits

    @property
    def limits_mps2(self) -> tuple[float, float]:
        """Lowest and highest representable value (two's complement)."""
        half = 2 ** (self.bits - 1)
        return -half * self.lsb_mps2, (half - 1) * self.lsb_mps2

    def apply(self, accel_mps2: np.ndarray) -> np.ndarray:
        """Round to counts and clip at the range."""
        lo, hi = self.limits_mps2
        return np.clip(np.round(accel_mps2 / self.lsb_mps2) * self.lsb_mps2, lo, hi)
