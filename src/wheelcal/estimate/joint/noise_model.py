"""Noise model of the residual: per-axis AR(p) colour and cross-axis correlation.

MEMS noise is coloured by the sensor's digital low-pass filter, which shrinks
the effective number of independent samples; a covariance that assumed white
noise would be too optimistic.  We model each axis as an autoregressive process

    e_n = x_n + a₁ x_{n−1} + … + a_p x_{n−p}      (white innovations e)

with p chosen by AIC, and the innovations of the three axes as jointly Gaussian
with covariance Σ_e.  Whitening (FIR filter A(z) per axis, then L⁻¹ with
Σ_e = L Lᵀ) turns the problem into ordinary least squares with unit-variance
errors: the ML fit of the whitened problem is the generalised-least-squares
estimate and (J̃ᵀJ̃)⁻¹ its covariance (the Cramér–Rao bound for Gaussian noise).
The first p samples of each filtered series are dropped (conditional likelihood).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint.columns import column_means, row_gram
from wheelcal.model import ar_variance_gain, fir_filter

#: Whitening a Jacobian takes one 3 × 3 product per tap up to this AR order (fewer passes
#: over the columns); above it the per-axis FIR wins (``benchmarks/bench_whiten.py``).
_TAP_PRODUCTS_UP_TO = 2
#: A residual's FIR with more taps than this is numpy's convolution (one pass in C; a
#: scaled add per tap took 2–3× as long at a 400 Hz road's 80 taps, as long at 24).
_CONVOLVE_FROM_TAPS = 32


@dataclass(frozen=True, eq=False)
class NoiseModel:
    """Per-axis AR whitening filters and the innovation covariance."""

    ar_polynomials: tuple[np.ndarray, np.ndarray, np.ndarray]  # [1, a₁, …] per axis
    innovation_cov: np.ndarray  # (3, 3)

    def __post_init__(self) -> None:
        polys = tuple(np.asarray(a, dtype=float) for a in self.ar_polynomials)
        if len(polys) != 3 or any(a[0] != 1.0 for a in polys):
            raise ValueError("need three AR polynomials with leading coefficient 1")
        cov = np.asarray(self.innovation_cov, dtype=float)
        object.__setattr__(self, "ar_polynomials", polys)
        object.__setattr__(self, "innovation_cov", cov)
        object.__setattr__(self, "_gains", np.array([ar_variance_gain(a) for a in polys]))
        chol = np.linalg.cholesky(cov)
        object.__setattr__(self, "_inv_chol", np.tril(np.linalg.inv(chol)))

    @classmethod
    def white(cls, std_mps2) -> NoiseModel:
        """Independent white noise with the given std per axis."""
        std = np.broadcast_to(np.asarray(std_mps2, dtype=float), (3,))
        return cls((np.ones(1), np.ones(1), np.ones(1)), np.diag(std**2))

    @classmethod
    def from_ar(cls, ar_polynomial: np.ndarray, innovation_std_mps2) -> NoiseModel:
        """The same AR polynomial on each axis, independent innovations."""
        a = np.asarray(ar_polynomial, dtype=float)
        std = np.broadcast_to(np.asarray(innovation_std_mps2, dtype=float), (3,))
        return cls((a, a, a), np.diag(std**2))

    @classmethod
    def estimate(cls, residual_mps2: np.ndarray, max_order: int = 10) -> NoiseModel:
        """Fit AR(p) per axis (Yule–Walker, p by AIC) and the innovation covariance."""
        r = np.asarray(residual_mps2, dtype=float)
        mean = column_means(r)
        # One axis at a time: a few copies of one column, never of the whole (N, 3).
        polys = tuple(_yule_walker_aic(r[:, i] - mean[i], max_order) for i in range(3))
        p = max(a.size - 1 for a in polys)
        innov = np.empty((3, max(r.shape[0] - p, 0)))  # rows: contiguous per axis
        for i in range(3):
            innov[i] = fir_filter(polys[i], r[:, i] - mean[i])[p:]
        cov = row_gram(innov) / max(innov.shape[1], 1)
        # Guard against a degenerate axis (e.g. a constant channel).
        cov += np.eye(3) * 1e-18 * max(np.trace(cov), 1e-30)
        return cls(polys, cov)

    @property
    def order(self) -> int:
        """Largest AR order over the axes."""
        return max(a.size - 1 for a in self.ar_polynomials)

    @property
    def marginal_std_mps2(self) -> np.ndarray:
        """Std of the noise itself per axis (what a datasheet would quote)."""
        return np.sqrt(np.diag(self.innovation_cov) * self._gains)

    @property
    def long_run_std_mps2(self) -> np.ndarray:
        """σ_e/|A(1)| per axis: √(2π·PSD at 0), the std that matters for slow signals."""
        return np.sqrt(np.diag(self.innovation_cov)) / np.abs(
            [a.sum() for a in self.ar_polynomials]
        )

    @property
    def effective_sample_fraction(self) -> np.ndarray:
        """(marginal / long-run variance) per axis: < 1 when low-pass noise shrinks the sample."""
        return (self.marginal_std_mps2 / self.long_run_std_mps2) ** 2

    @property
    def cross_correlation(self) -> np.ndarray:
        """Correlation matrix of the innovations across axes."""
        d = np.sqrt(np.diag(self.innovation_cov))
        return self.innovation_cov / np.outer(d, d)

    def whiten(
        self, residual: np.ndarray, jacobian: np.ndarray | None = None, overwrite: bool = False
    ):
        """Whiten a residual (N, 3) and optionally a Jacobian (P, 3, N).

        Returns ``(r, j)`` with r of shape (3, M) and j of shape (P, 3, M),
        M = N − p: unit-variance, uncorrelated errors, so the Fisher matrix is
        ``j.reshape(P, -1) @ j.reshape(P, -1).T``.  ``overwrite`` lets white
        noise (p = 0) whiten the Jacobian in its own buffer (no copy).
        """
        p = self.order
        inv_chol = self._inv_chol
        r = np.empty((3, residual.shape[0] - p))
        for i, a in enumerate(self.ar_polynomials):
            col = residual[:, i]
            if a.size == 1:
                r[i] = col[p:]
            elif a.size > _CONVOLVE_FROM_TAPS:  # one pass in C (same sums, another order)
                r[i] = np.convolve(col, a)[p : col.size]
            else:
                r[i] = fir_filter(a, col)[p:]
        r = inv_chol @ r
        if jacobian is None:
            return r, None
        size, _, n = jacobian.shape
        if p == 0 and overwrite:  # white, in place: row i of L⁻¹ needs rows ≤ i, so i = 2, 1, 0
            for i in (2, 1, 0):
                row = jacobian[:, i, :]
                row *= inv_chol[i, i]
                for k in range(i):
                    if inv_chol[i, k] != 0.0:
                        row += inv_chol[i, k] * jacobian[:, k, :]
            return r, jacobian
        if p == 0:  # white: L⁻¹ across axes in one batched product
            return r, np.matmul(inv_chol, jacobian)
        m = n - p
        if p <= _TAP_PRODUCTS_UP_TO:
            # Σ_k C_k x(t − k) with C_k = L⁻¹ diag(a_k) (a_k of each axis): one batched 3 × 3
            # product per tap, the FIR and L⁻¹ together.
            taps = self.tap_matrices
            # (A product into a preallocated ``out`` measured ~2× slower than into its own.)
            j = np.matmul(taps[0], jacobian[:, :, p:])
            for k in range(1, p + 1):
                j += np.matmul(taps[k], jacobian[:, :, p - k : n - k])
            return r, j
        # Longer filters: the FIR axis by axis into one (P, 3, M) buffer, then L⁻¹ across
        # axes in one batched product.  The FIR is numpy's convolution, row by row, of its
        # M valid outputs (one pass in C, what scipy's lfilter computes, bit for bit,
        # without its full-length rows and their copy; a scaled add per tap over the
        # columns took 3× as long at a road's 24 taps; the sums differ from those in their
        # order only, ~5e-16 relative).
        filtered = np.empty((size, 3, m))
        for i, a in enumerate(self.ar_polynomials):
            if a.size == 1:
                np.copyto(filtered[:, i, :], jacobian[:, i, p:])
                continue
            rows = jacobian[:, i, :]
            start = p - (a.size - 1)  # an axis of lower order starts later
            for k in range(size):
                filtered[k, i, :] = np.convolve(rows[k, start:], a, mode="valid")
        return r, np.matmul(inv_chol, filtered)

    @functools.cached_property
    def tap_matrices(self) -> np.ndarray:
        """(p + 1, 3, 3): C_k = L⁻¹ diag(a_k over the axes), a_k = 0 past an axis's order."""
        taps = np.zeros((self.order + 1, 3))
        for i, a in enumerate(self.ar_polynomials):
            taps[: a.size, i] = a
        return self._inv_chol[None, :, :] * taps[:, None, :]

    def to_dict(self) -> dict:
        """Summary for reports."""
        return {
            "model": "AR per axis + correlated innovations",
            "ar_order": [int(a.size - 1) for a in self.ar_polynomials],
            "ar_polynomials": [a.tolist() for a in self.ar_polynomials],
            "marginal_std_mps2": self.marginal_std_mps2.tolist(),
            "long_run_std_mps2": self.long_run_std_mps2.tolist(),
            "effective_sample_fraction": self.effective_sample_fraction.tolist(),
            "innovation_correlation": self.cross_correlation.tolist(),
        }


def _yule_walker_aic(x: np.ndarray, max_order: int) -> np.ndarray:
    """AR polynomial [1, a₁…a_p] with p ≤ max_order minimising AIC (Levinson–Durbin)."""
    n = x.size
    # Biased autocovariance for the few lags needed (direct sums beat an FFT here).
    acov = (np.array([x[: n - k] @ x[k:] for k in range(max_order + 1)]) / n).tolist()
    if acov[0] <= 0:
        return np.ones(1)
    # The recursion on Python floats: a dozen coefficients, where numpy's per-call
    # overhead would cost more than the arithmetic.
    best_a, best_aic = [1.0], n * math.log(acov[0])
    a = [1.0]
    err = acov[0]
    for k in range(1, max_order + 1):
        # Levinson–Durbin recursion for the order-k predictor.
        refl = -(acov[k] + sum(a[j] * acov[k - j] for j in range(1, k))) / err
        extended = [*a, 0.0]
        a = [extended[j] + refl * extended[k - j] for j in range(k + 1)]
        err *= 1.0 - refl**2
        if err <= 0:
            break
        aic = n * math.log(err) + 2 * k
        if aic < best_aic:
            best_a, best_aic = a, aic
    return np.array(best_a)
