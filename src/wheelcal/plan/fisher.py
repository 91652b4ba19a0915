"""Fisher information of a planned recording, exact or on a decimated grid.

For Gaussian noise whitened by the AR filter A(z) of each axis and L⁻¹ across
axes (:class:`~wheelcal.estimate.joint.noise_model.NoiseModel`), the Fisher matrix is a
sum over samples,

    F = Σ_n J̃_n J̃_nᵀ,     J̃_n = L⁻¹ Σ_k a_k J_{n−k}                      (*)

(J = ∂v/∂x of eq. 6 at the planned truth).  The exact F (``stride=1``) uses
every sample.  A mounting search needs thousands of F's, so it uses a
decimated grid: the whitened samples are cut into blocks of ``stride``
consecutive samples and each block is represented by its middle sample n_m,
weighted by the block length w_m,

    F ≈ Σ_m w_m J̃_{n_m} J̃_{n_m}ᵀ.

J̃_{n_m} itself is still exact: (*) is an FIR of order p, so J is evaluated at
the p+1 full-rate instants n_m, n_m−1, …, n_m−p and filtered there — the
colour of the noise is honoured however coarse the grid.

Why scaling a decimated sum is accurate (Poisson summation).  The summand
g(t) = J̃(t)J̃(t)ᵀ is a smooth function of time whose only fast content comes
from ϑ(t): every column of J is a combination of 1, cos ϑ, sin ϑ with
polynomial envelopes (eq. 1–2), so a product of two columns holds harmonics
0, 1 and 2 of the turn frequency f(t) = ω(t)/2π.  Sampling g every T = stride/rate
seconds gives Σ_m T g(mT) = Σ_l Ĝ(l/T): the l = 0 term is the integral
(= the full-rate sum / rate, up to edge terms of relative size ~stride/N), and
the aliases l ≠ 0 vanish as long as 1/T stays well above the band of g,
2 f_max.  :func:`decimation_stride` keeps ≥ ``samples_per_turn`` (16) samples per
turn at the fastest spin, i.e. 1/T ≥ 8 × (2 f_max); the tests compare decimated
and full-grid bounds (agreement well below 1 %).
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.joint import (
    Bound,
    NoiseModel,
    accumulate,
    covariance_from_fisher,
    nuisance_extra,
    report_transform,
    transform_covariance,
)
from wheelcal.model import CalibrationParams, ParameterLayout, evaluate, nuisance_sensitivity

#: Bound on the retained instants per chunk (memory: (P + Q) × 3 × chunk × (p + 1)).
_CHUNK_INSTANTS = 8192


def fisher_information(
    params: CalibrationParams,
    t_s: np.ndarray,
    noise: NoiseModel,
    layout: ParameterLayout,
    nuisances: tuple[str, ...] = (),
    stride: int = 1,
) -> np.ndarray:
    """F = J̃ᵀJ̃ over [free parameters | nuisance columns] at ``params`` (module docstring).

    Parameters
    ----------
    params:
        The point of evaluation (the planned truth).
    t_s:
        Centred sample times of the planned recording, uniformly spaced.
    noise:
        Whitening model of the noise.
    layout:
        Free parameters.
    nuisances:
        Fixed quantities (``radius_m``, ``tilt_rad``, ``gravity_mps2``) whose
        sensitivities ∂v/∂q are appended as extra columns, as the joint fit does
        for its systematic budget.
    stride:
        1 for the exact sum over every sample (the estimator's own chunked
        accumulation); > 1 for the decimated, re-weighted sum.

    Returns
    -------
    numpy.ndarray
        Square matrix of size ``layout.size + len(nuisances)``.
    """
    t = np.asarray(t_s, dtype=float)
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    if stride == 1:
        clean = evaluate(params, t).predicted_mps2  # zero residual: only J̃ᵀJ̃ matters
        extra = nuisance_extra(list(nuisances)) if nuisances else None
        return accumulate(params, t, clean, layout, noise, extra=extra).hessian
    return _decimated_fisher(params, t, noise, layout, nuisances, stride)


def _decimated_fisher(params, t, noise, layout, nuisances, stride) -> np.ndarray:
    p = noise.order
    n = t.size
    if n <= p:
        raise ValueError("fewer samples than the order of the noise model")
    # Blocks of `stride` whitened samples (indices p … n−1), midpoint representatives.
    starts = np.arange(p, n, stride)
    weights = (np.minimum(starts + stride, n) - starts).astype(float)
    centres = starts + (weights.astype(int) - 1) // 2
    polys = noise.ar_polynomials
    inv_chol = np.linalg.inv(np.linalg.cholesky(noise.innovation_cov))
    size = layout.size + len(nuisances)
    fisher = np.zeros((size, size))
    lags = np.arange(p + 1)
    for lo in range(0, centres.size, _CHUNK_INSTANTS):
        c = centres[lo : lo + _CHUNK_INSTANTS]
        w = weights[lo : lo + _CHUNK_INSTANTS]
        idx = (c[:, None] - lags[None, :]).reshape(-1)  # (m, p+1): n_m, n_m−1, …
        out = evaluate(params, t[idx], layout, jacobian=True)
        columns = [out.jacobian]
        if nuisances:
            columns.append(
                np.stack([nuisance_sensitivity(params, t[idx], q, out).T for q in nuisances])
            )
        jac = np.concatenate(columns, axis=0).reshape(size, 3, c.size, p + 1)
        # Eq. (*): FIR of each axis at the retained instants, then L⁻¹ across axes.
        filtered = np.empty((size, 3, c.size))
        for i, a in enumerate(polys):
            filtered[:, i, :] = jac[:, i, :, : a.size] @ a
        whitened = np.einsum("ij,pjm->pim", inv_chol, filtered)
        jt = (whitened * np.sqrt(w)).reshape(size, -1)
        fisher += jt @ jt.T
    return fisher


def bound_from_fisher(
    params: CalibrationParams, layout: ParameterLayout, fisher: np.ndarray
) -> Bound:
    """Cramér–Rao bound on the reported parameters from F over the free ones."""
    size = layout.size
    cov_x = covariance_from_fisher(fisher[:size, :size])
    names, values, g = report_transform(params, layout)
    return Bound(
        names=names,
        values=values,
        covariance=transform_covariance(g, cov_x),
        fisher=fisher[:size, :size],
    )
