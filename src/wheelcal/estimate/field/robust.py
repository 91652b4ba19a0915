"""σ that stay honest when the road's vibration is not the noise model's: the sandwich.

The joint fit's σ are the inverse Fisher information of its noise model —
stationary, coloured per axis.  A road's vibration is neither: it follows the
vehicle's speed, and it shakes along the world's vertical, which turns with the
wheel in the sensor's frame (its power on the in-plane axes swings at 2ϑ).  The
estimate stays consistent (the noise is zero-mean), but its spread is not what
the Fisher information says.  The sandwich covariance

    C = H⁻¹ M H⁻¹,   H = J̃ᵀJ̃ (+ the priors),   M = Σ_b g_b g_bᵀ,   g_b = J̃_bᵀ r̃_b

with the whitened score summed over blocks b of ``BLOCK_S`` (longer than the
noise's memory) takes the spread from the residuals themselves (White 1982;
the blocks make it robust to what correlation the whitening leaves).
:func:`robust_result` reports the larger of it and the model's σ per parameter
(the model's covariance scaled up where the sandwich is wider).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wheelcal.estimate.joint.information import covariance_from_fisher
from wheelcal.estimate.joint.normal_equations import effect_priors
from wheelcal.estimate.joint.reporting import report_transform, transform_covariance
from wheelcal.estimate.joint.result import CalibrationResult
from wheelcal.model import evaluate

#: The score is summed over blocks of this many seconds.
BLOCK_S = 1.0
#: Samples per evaluation (memory: P × 3 × this doubles).
_CHUNK = 20_000


def sandwich_covariance(result: CalibrationResult, accel_mps2: np.ndarray) -> np.ndarray:
    """C = H⁻¹ M H⁻¹ in the reported parameters (module docstring).

    ``accel_mps2`` are the samples ``result`` was fitted to (its window).
    """
    params, layout, noise = result.params, result.layout, result.noise
    t = result.centred_time_s
    p = noise.order
    rate_hz = 1.0 / float(np.median(np.diff(t)))
    block = max(p + 1, round(BLOCK_S * rate_hz))
    size = layout.size
    hess = np.zeros((size, size))
    meat = np.zeros((size, size))
    for start in range(0, t.size, _CHUNK):
        stop = min(t.size, start + _CHUNK + p)
        out = evaluate(params, t[start:stop], layout, jacobian=True)
        residual = out.predicted_mps2 - accel_mps2[start:stop]
        rw, jw = noise.whiten(residual, out.jacobian)  # (3, M), (P, 3, M)
        flat = jw.reshape(size, -1)
        hess += flat @ flat.T
        score = np.einsum("pim,im->pm", jw, rw)  # per whitened sample
        edges = np.arange(0, score.shape[1], block)
        sums = np.add.reduceat(score, edges, axis=1)  # (P, blocks)
        meat += sums @ sums.T
        if stop == t.size:
            break
    prior = effect_priors(params, layout)
    if prior is not None:
        hess[np.arange(size), np.arange(size)] += prior[2]
    bread = covariance_from_fisher(hess)
    finite = np.isfinite(np.diag(bread))
    clean = np.where(np.isfinite(bread), bread, 0.0)
    cov = clean @ meat @ clean
    cov[~finite, :] = np.nan
    cov[:, ~finite] = np.nan
    cov[~finite, ~finite] = np.inf
    _, _, g = report_transform(params, layout)
    return transform_covariance(g, cov)


def robust_result(result: CalibrationResult, accel_mps2: np.ndarray) -> CalibrationResult:
    """``result`` with each σ the larger of the model's and the sandwich's (module docstring)."""
    model = result.covariance
    sandwich = sandwich_covariance(result, accel_mps2)
    sd_model = np.sqrt(np.diag(model))
    sd_sandwich = np.sqrt(np.abs(np.diag(sandwich)))
    with np.errstate(invalid="ignore", divide="ignore"):
        factor = np.where(
            np.isfinite(sd_model) & np.isfinite(sd_sandwich) & (sd_model > 0),
            np.maximum(sd_sandwich / sd_model, 1.0),
            1.0,
        )
    covariance = model * np.outer(factor, factor)
    return dataclasses.replace(result, covariance=covariance)
