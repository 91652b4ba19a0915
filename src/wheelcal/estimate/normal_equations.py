"""Whitened normal equations, accumulated in cache-sized chunks.

Levenberg–Marquardt, the Fisher information, the systematic budget and the
score tests of the closed loop need only

    cost = ‖r̃‖²,   H = J̃ᵀJ̃,   g = J̃ᵀr̃

of the whitened residual r̃ and Jacobian J̃ — never J̃ itself.  Accumulating
them over chunks of samples keeps memory flat (a 1.8 M-sample recording would
otherwise need a 650 MB Jacobian) and the working set in cache.  The AR
whitening filter is an FIR of order p, so each chunk is evaluated from p
samples before its start and the first p outputs are dropped: the result is
identical to whitening the whole series at once.

``extra`` adds columns that are not free parameters (a nuisance sensitivity,
a candidate effect): H and g then cover [free | extra].
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.noise_model import NoiseModel
from wheelcal.model import CalibrationParams, ModelOutput, ParameterLayout, evaluate

#: Samples per chunk: ~12 MB of Jacobian for 18 columns; one chunk for a typical
#: 90 s / 200 Hz recording, bounded memory for long or fast ones.
CHUNK_SAMPLES = 32768

# (params, model output, chunk times) → (k, 3, n) extra columns at those times
ExtraColumns = Callable[[CalibrationParams, ModelOutput, np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class NormalEquations:
    """Sums over the whitened residual: cost, H = J̃ᵀJ̃ and g = J̃ᵀr̃ (r̃ = model − data)."""

    cost: float
    hessian: np.ndarray | None
    gradient: np.ndarray | None
    entries: int  # number of whitened residual entries


def accumulate(
    params: CalibrationParams,
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    layout: ParameterLayout,
    noise: NoiseModel,
    jacobian: bool = True,
    extra: ExtraColumns | None = None,
    chunk: int = CHUNK_SAMPLES,
) -> NormalEquations:
    """Accumulate cost, J̃ᵀJ̃ and J̃ᵀr̃ of the whitened residual (model − data)."""
    n = t_s.size
    p = noise.order
    cost = 0.0
    entries = 0
    hess = grad = None
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        lo = max(0, start - p)  # p samples of history for the FIR whitening
        out = evaluate(params, t_s[lo:stop], layout, jacobian=jacobian)
        resid = out.predicted_mps2 - accel_mps2[lo:stop]
        if not jacobian:
            rw, _ = noise.whiten(resid)
            cost += float(np.sum(rw * rw))
            entries += rw.size
            continue
        rw, jw = noise.whiten(resid, out.jacobian)
        jt = jw.reshape(jw.shape[0], -1)
        r_flat = rw.reshape(-1)
        blocks = [jt]
        if extra is not None:  # whitened separately: no copy of the big Jacobian
            _, ew = noise.whiten(np.zeros_like(resid), extra(params, out, t_s[lo:stop]))
            blocks.append(ew.reshape(ew.shape[0], -1))
        h_chunk = _cross(blocks)
        g_chunk = np.concatenate([b @ r_flat for b in blocks])
        if hess is None:
            hess, grad = h_chunk, g_chunk
        else:
            hess += h_chunk
            grad += g_chunk
        cost += float(r_flat @ r_flat)
        entries += r_flat.size
    return NormalEquations(cost=cost, hessian=hess, gradient=grad, entries=entries)


def _cross(blocks: list[np.ndarray]) -> np.ndarray:
    """[B₀; B₁; …] [B₀; B₁; …]ᵀ from row blocks without stacking them."""
    if len(blocks) == 1:
        return blocks[0] @ blocks[0].T
    sizes = [b.shape[0] for b in blocks]
    out = np.empty((sum(sizes), sum(sizes)))
    edges = np.concatenate([[0], np.cumsum(sizes)])
    for i, bi in enumerate(blocks):
        for j in range(i, len(blocks)):
            block = bi @ blocks[j].T
            out[edges[i] : edges[i + 1], edges[j] : edges[j + 1]] = block
            out[edges[j] : edges[j + 1], edges[i] : edges[i + 1]] = block.T
    return out
