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
