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


def chunking(layout: ParameterLayout, t_s: np.ndarray, chunk: int | None) -> tuple[int, bool]:
    """Samples per chunk, and whether the rows are sparse (a spline: two knot intervals)."""
    spline = next((e for e in layout.effects if e.name == "spin_spline"), None)
    if spline is None or spline.size < 8 or t_s.size < 2:
        return chunk or CHUNK_SAMPLES, False
    rate = (t_s.size - 1) / max(float(t_s[-1] - t_s[0]), 1e-12)
    return chunk or max(256, int(2 * spline.spacing_s * rate)), True


def accumulate(
    params: CalibrationParams,
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    layout: ParameterLayout,
    noise: NoiseModel,
    jacobian: bool = True,
    extra: ExtraColumns | None = None,
    chunk: int | None = None,
) -> NormalEquations:
    """Accumulate cost, J̃ᵀJ̃ and J̃ᵀr̃ of the whitened residual (model − data).

    With a local basis in the layout (a wheel-angle spline), chunks follow its
    knots and the Gram products skip the rows that are zero over a chunk.
    """
    n = t_s.size
    chunk, sparse = chunking(layout, t_s, chunk)
    p = noise.order
    cost = 0.0
    entries = 0
    hess = grad = None
    extra_size = None  # learnt from the first chunk
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        lo = max(0, start - p)  # p samples of history for the FIR whitening
        if not jacobian:
            out = evaluate(params, t_s[lo:stop], layout)
            rw, _ = noise.whiten(out.predicted_mps2 - accel_mps2[lo:stop])
            cost += float(np.sum(rw * rw))
            entries += rw.size
            continue
        # One buffer for the free parameters' columns and the extra ones: one
        # whitening and one Gram product (cheaper than blocks, measured).
        rows = layout.size + (extra_size or 0)
        buf = np.empty((rows, 3, stop - lo))
        out = evaluate(params, t_s[lo:stop], layout, jacobian=True, out=buf[: layout.size])
        if extra is not None:
            cols = extra(params, out, t_s[lo:stop])
            if extra_size is None:  # first chunk: now we know how many
                extra_size = cols.shape[0]
                buf = np.concatenate([buf, cols])
            else:
                buf[layout.size :] = cols
        rw, jw = noise.whiten(out.predicted_mps2 - accel_mps2[lo:stop], buf)
        jt = jw.reshape(jw.shape[0], -1)
        r_flat = rw.reshape(-1)
        if hess is None:
            hess = np.zeros((jt.shape[0], jt.shape[0]))
            grad = np.zeros(jt.shape[0])
        add_gram(hess, grad, jt, r_flat, sparse)
        cost += float(r_flat @ r_flat)
        entries += r_flat.size
    return NormalEquations(cost=cost, hessian=hess, gradient=grad, entries=entries)


def add_gram(
    hess: np.ndarray, grad: np.ndarray, jt: np.ndarray, r: np.ndarray, sparse: bool
) -> None:
    """Add J Jᵀ to ``hess`` and J r to ``grad`` (only J's non-zero rows when ``sparse``).

    A spline of the wheel angle has columns that live on a few knot intervals:
    over a short chunk most of its rows are zero, and the Gram product of the
    others is all that costs.
    """
    if not sparse:
        hess += jt @ jt.T
        grad += jt @ r
        return
    active = np.flatnonzero(np.any(jt != 0.0, axis=1))
    sub = jt[active]
    hess[np.ix_(active, active)] += sub @ sub.T
    grad[active] += sub @ r
