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
from scipy.fft import next_fast_len, rfft

from wheelcal.estimate import RestSegment, pooled_noise_std

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
    # Axis by axis: temporaries of one column, never of the whole (N, 3).  (Also much
    # faster: numpy reduces an (N, 3) array over axis 0 a row of three at a time.)
    mean = np.array([r[:, k].mean() for k in range(3)])
    total_var = np.array([np.mean((r[:, k] - mean[k]) ** 2) for k in range(3)])
    turns = angle[-1] / (2 * np.pi)
    if r.shape[0] < 64 or turns < 4 or not np.all(np.diff(angle) >= 0):
        return np.sqrt(total_var), np.zeros(3)
    # Resampled to a length the FFT factors well (≥ N, 2·3·5·7·11-smooth): a prime length
    # takes Bluestein's algorithm, 10–15× slower (1.8 M samples: 0.9 s per axis).
    size = next_fast_len(r.shape[0], real=True)
    grid = np.linspace(0.0, angle[-1], size)
    bins = size // 2 + 1
    order = np.arange(bins) / turns  # cycles per turn
    band = np.round(order).astype(np.int64)  # the nearest order
    between = np.abs(order - band) > HARMONIC_HALF_WIDTH
    del order
    bands = _Bands(band, between)
    share = np.empty(3)
    for k in range(3):  # one axis at a time: temporaries of one column, never of (N, 3)
        uniform = np.interp(grid, angle, r[:, k])
        uniform -= uniform.mean()
        power = np.abs(rfft(uniform)) ** 2
        del uniform
        power[0] = 0.0
        share[k] = min(bands.floor_sum(power) / max(float(power.sum()), 1e-300), 1.0)
    broadband_var = total_var * share
    return np.sqrt(broadband_var), np.sqrt(np.maximum(total_var - broadband_var, 0.0))


class _Bands:
    """Periodogram bins grouped by their nearest order (one band per order).

    ``band`` is non-decreasing, so each band is a run of bins.  The floor of a
    band is the median of its bins between the orders, ÷ ln 2 (the median of
    χ²₂ bins is ln 2 × their mean).  The medians of all bands come from one
    table, a row per band padded with +∞, sorted row by row — exactly
    ``np.median`` per band, without a Python loop over the orders (and ~15×
    faster than one sort of all bins keyed by band).  A band with no bins
    between the orders takes those of its neighbours (|order − k| ≤ 1), and
    keeps its own power when there are none either.
    """

    def __init__(self, band: np.ndarray, between: np.ndarray) -> None:
        self.band, self.between = band, between
        count = int(band[-1]) + 1
        counts = np.bincount(band[between], minlength=count)
        starts = np.cumsum(counts) - counts
        self.has = counts > 0
        size, first = counts[self.has], starts[self.has]
        column = np.arange(size.max() if size.size else 0)
        # Row b of the table: the between-bins of band b, then the padding index
        # (one past the last bin, where floor_sum puts +∞).
        self.table = np.where(column < size[:, None], first[:, None] + column, int(counts.sum()))
        self.rows = np.arange(size.size)
        self.lo, self.hi = (size - 1) // 2, size // 2
        self.size = np.bincount(band, minlength=count)  # bins per band

    def floor_sum(self, power: np.ndarray) -> float:
        """Σ over the bins of each bin's band floor (the broadband part of Σ power)."""
        padded = np.append(power[self.between], np.inf)[self.table]
        padded.sort(axis=1)
        medians = 0.5 * (padded[self.rows, self.lo] + padded[self.rows, self.hi])
        total = float(self.size[self.has] @ medians) / np.log(2.0)
        for k in np.flatnonzero(~self.has):  # rare: a band without bins between the orders
            in_band = self.band == k
            ref = (np.abs(self.band - k) <= 1) & self.between
            if np.any(ref):
                total += float(in_band.sum() * np.median(power[ref])) / np.log(2.0)
            else:
                total += float(power[in_band].sum())
        return total


def noise_reference(
    residual_mps2: np.ndarray, theta_rad: np.ndarray, rests: tuple[RestSegment, ...]
) -> NoiseReference:
    """The noise floor (rests, else the spectrum) and the residual's split against it."""
    r = np.asarray(residual_mps2, dtype=float)
    rms = np.sqrt([np.mean(r[:, k] ** 2) for k in range(3)])
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
