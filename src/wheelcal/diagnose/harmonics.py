"""Residual spectrum against harmonics of the wheel angle ϑ.

Effects that the model lacks often repeat every turn (an imbalance, a
nonlinearity of a rotating gravity signal): they show as residual power at
integer multiples of the wheel rate.  For k = 1…K the residual of each axis is
least-squares fitted with cos kϑ and sin kϑ; the amplitude is compared with
what white noise of the residual's level would give, σ·√(4/N)·(√π/2) on average.
"""

from __future__ import annotations

import numpy as np


def wheel_harmonics(
    theta_rad: np.ndarray, residual_mps2: np.ndarray, max_harmonic: int = 6
) -> dict:
    """Amplitude (m/s²) per harmonic and axis, and the noise reference."""
    n = theta_rad.size
    rows = []
    for k in range(1, max_harmonic + 1):
        basis = np.column_stack([np.cos(k * theta_rad), np.sin(k * theta_rad)])
        coef, *_ = np.linalg.lstsq(basis, residual_mps2 - residual_mps2.mean(axis=0), rcond=None)
        rows.append(np.hypot(coef[0], coef[1]))
    sigma = residual_mps2.std(axis=0)
    return {
        "harmonic": list(range(1, max_harmonic + 1)),
        "amplitude_mps2": np.array(rows).tolist(),
        "noise_reference_mps2": (sigma * np.sqrt(4.0 / n) * np.sqrt(np.pi) / 2).tolist(),
    }


def binned_mean_by_angle(
    theta_rad: np.ndarray, values: np.ndarray, bins: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean of ``values`` (N, 3) in ``bins`` equal bins of ϑ mod 2π.

    Returns
    -------
    centres_deg, mean, count
        Centres in degrees of the bins that hold samples, the per-axis mean
        there (B, 3) and the number of samples in each.
    """
    wrapped = np.mod(np.asarray(theta_rad, dtype=float), 2 * np.pi)
    index = np.minimum((wrapped * (bins / (2 * np.pi))).astype(np.int64), bins - 1)
    count = np.bincount(index, minlength=bins)
    sums = np.column_stack(
        [np.bincount(index, weights=values[:, k], minlength=bins) for k in range(3)]
    )
    filled = count > 0
    centres_deg = (np.arange(bins) + 0.5) * (360.0 / bins)
    return centres_deg[filled], sums[filled] / count[filled, None], count[filled]


def residual_by_wheel_angle(
    theta_rad: np.ndarray, residual_mps2: np.ndarray, bin_deg: float = 10.0
) -> dict:
    """The residual's mean per ``bin_deg`` of ϑ mod 360° (JSON-ready; bins without samples omitted).

    Effects that repeat every turn line up here while they hide in the noise
    against time (see :mod:`wheelcal.viz.session_rrd`); the batch overview
    draws these profiles for every session.
    """
    bins = round(360.0 / bin_deg)
    centres, mean, count = binned_mean_by_angle(theta_rad, np.asarray(residual_mps2), bins)
    return {
        "bin_deg": 360.0 / bins,
        "centres_deg": [float(c) for c in centres],
        "mean_mps2": [[float(v) for v in row] for row in mean],
        "samples": [int(c) for c in count],
    }
