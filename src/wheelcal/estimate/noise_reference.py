"""An independent noise reference: how much of the residual is the sensor's own noise.

The AR noise model of the joint fit is estimated from the fit's own residual,
so it absorbs whatever the model misses: a 1–2 m/s² misfit becomes "coloured
noise" and the σ grow to match.  To judge the model we need evidence the fit
did not produce:

1. **Rests** (:mod:`wheelcal.estimate.rests`): the scatter of the sensor at
   rest is its noise floor, measured without any model.
2. **Without rests, the residual's spectrum between the wheel harmonics.**
   Resampled at uniform steps of the fitted wheel angle ϑ, a model misfit
   lives at whole orders (cycles per turn: 0 for slow terms such as r ω² or a
   drifting offset, 1 for the rotating gravity, 2 for an anisotropy …), while
   noise and broadband vibration spread over all orders.  The periodogram's
   median between the orders (|order − k| > ¼), rescaled to its mean
   (÷ ln 2 for χ²₂ bins), interpolated across each order's band and summed
   (Parseval), gives the broadband part of the residual; the rest is the
   *harmonic* part, which the model should have explained.

``unexplained = √(max(rms² − floor², 0))`` per axis.  With rests the
spectrum still splits what is unexplained into broadband (vibration of the
bench while it turns) and harmonic (something the model lacks), which names
the cause in the warning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.rests import RestSegment, pooled_noise_std

#: Half-width of each order's band, in cycles per turn.
HARMONIC_HALF_WIDTH = 0.25


@dataclass(frozen=True, eq=False)
class NoiseReference:
    """The sensor's noise floor and what the residual holds beyond it (per axis, m/s²)."""

    floor_mps2: np.ndarray
    source: str  # "rests" or "spectrum"
    floor_dof: float  # effective samples behind the floor (its relative σ ≈ 1/√(2·dof))
    residual_rms_mps2: np.ndarray
    broadband_mps2: np.ndarray  # residual between the wheel harmonics
    harmonic_mps2: np.ndarray  # residual at the wheel harmonics, beyond the broadband level
    rests: tuple[RestSegment, ...] = ()

    @property
    def unexplained_mps2(self) -> np.ndarray:
        """√(rms² − floor²): residual the sensor's noise does not explain."""
        return np.sqrt(np.maximum(self.residual_rms_mps2**2 - self.floor_mps2**2, 0.0))

    @property
    def ratio(self) -> np.ndarray:
        """Residual RMS over the noise floor, per axis (≈ 1 when the model explains the data)."""
        return self.residual_rms_mps2 / np.maximum(self.floor_mps2, 1e-12)

    @property
    def vibration_mps2(self) -> np.ndarray:
        """Broadband residual beyond the floor: the bench shaking while the wheel turns."""
        return np.sqrt(np.maximum(self.broadband_mps2**2 - self.floor_mps2**2, 0.0))

    def to_dict(self) -> dict:
        """For the calibration JSON (``fit.noise_reference``)."""
        return {
            "source": self.source,
            "floor_mps2": self.floor_mps2.tolist(),
            "unexplained_mps2": self.unexplained_mps2.tolist(),
            "ratio": self.ratio.tolist(),
            "broadband_mps2": self.broadband_mps2.tolist(),
            "harmonic_mps2": self.harmonic_mps2.tolist(),
            "rests_s": [[r.start_s, r.end_s] for r in self.rests],
        }


def order_spectrum_split(
    residual_mps2: np.ndarray, theta_rad: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(broadband, harmonic) RMS per axis of a residual, split in the wheel-angle domain."""
    r = np.asarray(residual_mps2, dtype=float)
    angle = np.abs(np.asarray(theta_rad, dtype=float) - theta_rad[0])
    total_var = np.mean((r - r.mean(axis=0)) ** 2, axis=0)
    turns = angle[-1] / (2 * np.pi)
    if r.shape[0] < 64 or turns < 4 or not np.all(np.diff(angle) >= 0):
        return np.sqrt(total_var), np.zeros(3)
    grid = np.linspace(0.0, angle[-1], r.shape[0])
    uniform = np.column_stack([np.interp(grid, angle, r[:, k]) for k in range(3)])
    power = np.abs(np.fft.rfft(uniform - uniform.mean(axis=0), axis=0)) ** 2
    power[0] = 0.0
    order = np.arange(power.shape[0]) / turns  # cycles per turn
    nearest = np.round(order)
    between = np.abs(order - nearest) > HARMONIC_HALF_WIDTH
    floor = _band_floor(power, nearest.astype(np.int64), between)
    share = np.minimum(floor.sum(axis=0) / np.maximum(power.sum(axis=0), 1e-300), 1.0)
    broadband_var = total_var * share
    return np.sqrt(broadband_var), np.sqrt(np.maximum(total_var - broadband_var, 0.0))


def _band_floor(power: np.ndarray, band: np.ndarray, between: np.ndarray) -> np.ndarray:
    """Per bin, the median of its band's bins between the orders, ÷ ln 2 (χ²₂ median → mean).

    ``band`` (the nearest order) is non-decreasing, so each band is a run of
    bins: the medians of all bands come from one sort per axis grouped by band
    (exactly ``np.median`` per band, without a Python loop over the orders).
    A band with no bins between the orders takes those of its neighbours
    (|order − k| ≤ 1), and keeps its own power when there are none either.
    """
    bands = int(band[-1]) + 1
    ref_band = band[between]
    ref_power = power[between]
    counts = np.bincount(ref_band, minlength=bands)
    starts = np.cumsum(counts) - counts
    medians = np.empty((bands, power.shape[1]))
    has = counts > 0
    lo = starts[has] + (counts[has] - 1) // 2
    hi = starts[has] + counts[has] // 2
    for axis in range(power.shape[1]):
        ordered = ref_power[np.lexsort((ref_power[:, axis], ref_band)), axis]
        medians[has, axis] = 0.5 * (ordered[lo] + ordered[hi])
    floor = medians[band] / np.log(2.0)
    for k in np.flatnonzero(~has):  # rare: a band without bins between the orders
        in_band = band == k
        ref = (np.abs(band - k) <= 1) & between
        floor[in_band] = (
            np.median(power[ref], axis=0) / np.log(2.0) if np.any(ref) else power[in_band]
        )
    return floor


def noise_reference(
    residual_mps2: np.ndarray, theta_rad: np.ndarray, rests: tuple[RestSegment, ...]
) -> NoiseReference:
    """The noise floor (rests, else the spectrum) and the residual's split against it."""
    r = np.asarray(residual_mps2, dtype=float)
    rms = np.sqrt(np.mean(r**2, axis=0))
    broadband, harmonic = order_spectrum_split(r, theta_rad)
    pooled = pooled_noise_std(rests)
    if pooled is not None:
        floor, dof = pooled
        source = "rests"
    else:
        floor, dof = broadband, float(r.shape[0]) / 2
        source = "spectrum"
    return NoiseReference(
        floor_mps2=np.asarray(floor, dtype=float),
        source=source,
        floor_dof=float(dof),
        residual_rms_mps2=rms,
        broadband_mps2=broadband,
        harmonic_mps2=harmonic,
        rests=tuple(rests),
    )
