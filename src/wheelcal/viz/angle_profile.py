"""The residual folded on the wheel angle ϑ, with the σ of each bin's mean.

The mean per bin of ϑ mod 360° is :func:`wheelcal.estimate.residual_profile.binned_mean_by_angle`.
Its σ here treats each *turn* as one independent draw (a cluster): the
samples of one bin that fall in one turn lie a few milliseconds apart and
share coloured noise, samples of different turns do not.  So, with n_kb the
samples and m_kb their mean in bin b of turn k, N_b = Σ_k n_kb and m_b the
bin's mean,

    σ²(m_b) = K_b/(K_b − 1) · Σ_k n_kb² (m_kb − m_b)² / N_b²

(the cluster-robust variance of a mean over the K_b turns that reach the bin).
It needs no noise model and stays honest under a low-pass filter; with white
noise it equals σ²/N_b on average.  A bin mean further than 2σ from zero
is what noise alone gives about once in 20 bins; a pattern that repeats every
turn lies outside the band over many neighbouring bins.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class AngleProfile:
    """Mean residual per bin of ϑ and its σ (bins without samples left out)."""

    centres_deg: np.ndarray  # (B,)
    mean_mps2: np.ndarray  # (B, 3)
    std_of_mean_mps2: np.ndarray  # (B, 3); NaN where fewer than two turns reach a bin
    samples: np.ndarray  # (B,)


def angle_profile(theta_rad: np.ndarray, values: np.ndarray, bins: int) -> AngleProfile:
    """Mean of ``values`` (N, 3) per bin of ϑ mod 2π and the σ of that mean (module docstring).

    Parameters
    ----------
    theta_rad:
        The wheel angle at each sample, rad, *not* wrapped (its turn count
        groups the samples).
    values:
        (N, 3), e.g. the residual in m/s².
    bins:
        Equal bins over 360°.
    """
    theta = np.asarray(theta_rad, dtype=float).reshape(-1)
    v = np.asarray(values, dtype=float)
    turns = np.floor(theta / (2 * np.pi))
    wrapped = theta - 2 * np.pi * turns
    b = np.minimum((wrapped * (bins / (2 * np.pi))).astype(np.int64), bins - 1)
    k = (turns - turns.min()).astype(np.int64)
    cell = k * bins + b  # one cell per (turn, bin)
    size = int(cell.max()) + 1 if cell.size else 0
    n_cell = np.bincount(cell, minlength=size).astype(float)
    n_bin = np.bincount(b, minlength=bins).astype(float)
    filled = n_bin > 0
    occupied = np.flatnonzero(n_cell)
    cell_bin = occupied % bins
    turns_in_bin = np.bincount(cell_bin, minlength=bins).astype(float)
    mean = np.empty((bins, 3))
    var = np.empty((bins, 3))
    for axis in range(3):
        s_cell = np.bincount(cell, weights=v[:, axis], minlength=size)[occupied]
        s_bin = np.bincount(b, weights=v[:, axis], minlength=bins)
        m = np.divide(s_bin, n_bin, out=np.zeros(bins), where=filled)
        # n_kb (m_kb − m_b) = s_kb − n_kb m_b
        dev = s_cell - n_cell[occupied] * m[cell_bin]
        total = np.bincount(cell_bin, weights=dev**2, minlength=bins)
        with np.errstate(invalid="ignore", divide="ignore"):
            var[:, axis] = turns_in_bin / (turns_in_bin - 1) * total / n_bin**2
        mean[:, axis] = m
    var[turns_in_bin < 2] = np.nan
    centres = (np.arange(bins) + 0.5) * (360.0 / bins)
    return AngleProfile(
        centres_deg=centres[filled],
        mean_mps2=mean[filled],
        std_of_mean_mps2=np.sqrt(var[filled]),
        samples=n_bin[filled].astype(np.int64),
    )
