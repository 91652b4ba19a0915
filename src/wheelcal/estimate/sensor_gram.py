"""Gram blocks of the gain and offset columns, formed per axis instead of densely.

Before whitening, the gain and offset columns of the Jacobian live on one axis
each (:mod:`wheelcal.model.forward`): ∂v/∂γ_j = e_j s_j and ∂v/∂o_j = e_j.
The whitening W = L⁻¹ F (per-axis FIR F, then L⁻¹ across axes, Σ_e = L Lᵀ;
:mod:`wheelcal.estimate.noise_model`) maps such a column e_j x to L⁻¹ e_j f with
f = F_j x (for x = 1: the constant Σ_k a_{j,k} once the history is dropped).
So, for any other whitened column c̃ (3, M),

    ⟨c̃, W e_j x⟩ = Σ_i (L⁻¹)_{ij} ⟨c̃_i, f⟩,      ⟨W e_j x, W e_k y⟩ = (Σ_e⁻¹)_{jk} ⟨f, h⟩,

(h = F_k y).  The six columns then need neither whitening nor a place in the
dense Gram product: that product shrinks from (k + 6)² to k² rows², and the
cross terms take three thin products of the k whitened rows with the six
filtered series.  The sums are those of the dense product, to round-off.
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.noise_model import NoiseModel
from wheelcal.model.ar_process import fir_filter

#: The axis of each of the six columns: gain x, y, z, then offset x, y, z.
SENSOR_AXES = np.array([0, 1, 2, 0, 1, 2])
#: Samples per product of the cross terms (0.19 ms for 12 rows × 17 k samples, 0.37 in one).
BLOCK_SAMPLES = 4096


def sensor_series(sensed_mps2: np.ndarray, noise: NoiseModel) -> np.ndarray:
    """The six filtered series f (M, 6): F_j s_j for the gains, Σ_k a_{j,k} for the offsets.

    ``sensed_mps2`` (N, 3) is s = R a at the samples (the p first outputs dropped,
    as the whitening drops them).
    """
    p = noise.order
    m = sensed_mps2.shape[0] - p
    series = np.empty((m, 6))
    for j, a in enumerate(noise.ar_polynomials):
        column = sensed_mps2[:, j]
        series[:, j] = column[p:] if a.size == 1 else fir_filter(a, column)[p:]
        series[:, 3 + j] = a.sum()
    return series


def sensor_gram(
    whitened: np.ndarray, series: np.ndarray, noise: NoiseModel
) -> tuple[np.ndarray, np.ndarray]:
    """Cross terms (k, 6) of whitened rows (k, 3, M) with the six columns, and their (6, 6) block.

    ``series`` from :func:`sensor_series`; columns ordered gain x, y, z, offset x, y, z.
    """
    inv_chol = noise.inverse_cholesky
    rows, _, m = whitened.shape
    flat = whitened.reshape(3 * rows, m)
    # ⟨c̃_i, f⟩ of every row and axis, by blocks of samples: one product over all of them
    # at once runs at half the speed (the series' rows leave the cache).
    products = np.zeros((3 * rows, 6))
    for start in range(0, m, BLOCK_SAMPLES):
        products += flat[:, start : start + BLOCK_SAMPLES] @ series[start : start + BLOCK_SAMPLES]
    products = products.reshape(rows, 3, 6)
    cross = products[:, 0, :] * inv_chol[0, SENSOR_AXES]
    cross += products[:, 1, :] * inv_chol[1, SENSOR_AXES]
    cross += products[:, 2, :] * inv_chol[2, SENSOR_AXES]
    precision = inv_chol.T @ inv_chol  # Σ_e⁻¹
    block = (series.T @ series) * precision[np.ix_(SENSOR_AXES, SENSOR_AXES)]
    return cross, block
