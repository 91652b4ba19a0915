"""Vibration of a wheel's hub: the road under a vehicle, or a hand at the bench.

The hub (the whole wheel) is shaken by a small translation whose acceleration,
in the carrier's axes (forward f, left l, up e_z; see
:mod:`wheelcal.simulate.field_kinematics`), is coloured Gaussian noise:

    x_k = e(t) · rms · ratio_k · (B * n_k)(t) / √G,

n_k white, B a Butterworth band-pass (``order`` per edge, so 2·order poles)
between ``band_hz`` — or a low-pass when the lower edge is ``None`` — and G the
filter's white-noise variance gain Σ h² (from its impulse response), so that
``rms · ratio_k`` is the marginal std where the envelope e(t) is 1.  The band's
top is held below 0.45 × the sample rate.  The envelope follows the vehicle's
speed, e = min(1, v / v_full)^p (zero at a standstill), or the hand phases of a
fixed axle (:meth:`~wheelcal.simulate.field_motion.AxleSpin.hand_envelope`).
A translation: the gyro sees it only through its g-sensitivity.

For a Cramér–Rao bound: the noise is x = e(t) · D · y(t) with D = diag(rms ·
ratio / √G) and y stationary with the power spectrum |B(e^{iω})|² of
:meth:`VibrationSpec.sos` (white innovations of unit variance); in the sensor's
axes it is further turned by Γ R Aᵀ(t) (the truth keeps the realised samples).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy import signal


@dataclass(frozen=True)
class VibrationSpec:
    """Coloured hub vibration (module docstring).

    Parameters
    ----------
    rms_mps2:
        Std (m/s²) of the vertical component where the envelope is 1.
    band_hz:
        (low, high) edges; low ``None`` for a low-pass.
    axis_ratio:
        Std of the (forward, left, up) components relative to ``rms_mps2``.
    follows:
        ``"speed"`` (the hub's speed, a road) or ``"hands"`` (a fixed axle's
        push and brake).
    full_speed_mps, speed_exponent:
        The speed envelope min(1, v / full_speed)^exponent.
    order:
        Butterworth order per band edge.
    """

    rms_mps2: float
    band_hz: tuple[float | None, float] = (5.0, 30.0)
    axis_ratio: tuple[float, float, float] = (0.5, 0.4, 1.0)
    follows: Literal["speed", "hands"] = "speed"
    full_speed_mps: float = 10.0
    speed_exponent: float = 0.5
    order: int = 2

    def __post_init__(self) -> None:
        if not (np.isfinite(self.rms_mps2) and self.rms_mps2 >= 0):
            raise ValueError(f"rms_mps2 must be finite and >= 0, got {self.rms_mps2}")
        low, high = self.band_hz
        if not (high > 0 and (low is None or 0 < low < high)):
            raise ValueError(f"band_hz must be (low, high) with 0 < low < high, got {self.band_hz}")
        ratio = np.asarray(self.axis_ratio, dtype=float)
        if ratio.shape != (3,) or np.any(ratio < 0) or not np.all(np.isfinite(ratio)):
            raise ValueError("axis_ratio needs three finite values >= 0")
        if self.follows not in ("speed", "hands"):
            raise ValueError(f"follows must be 'speed' or 'hands', got {self.follows!r}")
        if not (self.full_speed_mps > 0 and self.speed_exponent >= 0 and self.order >= 1):
            raise ValueError("full_speed_mps > 0, speed_exponent >= 0 and order >= 1 needed")

    def sos(self, rate_hz: float) -> np.ndarray:
        """The shaping filter B as second-order sections at ``rate_hz``."""
        low, high = self.band_hz
        high = min(high, 0.45 * rate_hz)
        if low is None:
            return signal.butter(self.order, high, btype="lowpass", fs=rate_hz, output="sos")
        if not low < high:
            raise ValueError(f"the band {self.band_hz} Hz lies above 0.45 × {rate_hz:g} Hz")
        return signal.butter(self.order, (low, high), btype="bandpass", fs=rate_hz, output="sos")

    def _settle_samples(self, rate_hz: float) -> int:
        """Samples for the filter's response to die out (20 time constants of its lowest edge)."""
        lowest = self.band_hz[0] or self.band_hz[1]
        return int(20 * rate_hz / (2 * np.pi * lowest)) + 10

    def variance_gain(self, rate_hz: float) -> float:
        """G = Σ h², the filter's output variance per unit white input."""
        impulse = np.zeros(8 * self._settle_samples(rate_hz))
        impulse[0] = 1.0
        return float(np.sum(signal.sosfilt(self.sos(rate_hz), impulse) ** 2))

    def envelope(self, speed_mps: np.ndarray) -> np.ndarray:
        """e(v) = min(1, v / full_speed)^exponent (0 at rest)."""
        ratio = np.minimum(1.0, np.abs(np.asarray(speed_mps, dtype=float)) / self.full_speed_mps)
        return ratio**self.speed_exponent

    def sample(self, n: int, rate_hz: float, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) stationary (forward, left, up) accelerations, envelope 1 (one normal draw)."""
        burn = self._settle_samples(rate_hz)
        white = rng.standard_normal((n + burn, 3))
        shaped = signal.sosfilt(self.sos(rate_hz), white, axis=0)[burn:]
        scale = self.rms_mps2 * np.asarray(self.axis_ratio) / np.sqrt(self.variance_gain(rate_hz))
        return shaped * scale
