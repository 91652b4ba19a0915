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

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint.fisher_quadrature import (
    QuadratureRows,
    quadrature_rows,
    stride_for,
    whitened_rows,
)
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.model import (
    CalibrationParams,
    ModelOutput,
    ParameterLayout,
    ReverseAt,
    evaluate,
    output_at_samples,
    reverse_pass,
)

#: Samples per chunk: ~12 MB of Jacobian for 18 columns; one chunk for a typical
#: 90 s / 200 Hz recording, bounded memory for long or fast ones.
CHUNK_SAMPLES = 32768

#: With a spline: two knot intervals per chunk, within these bounds (the Jacobian of
#: ~30 rows then stays in cache: 1.2-1.5x faster than 6400 samples for 16 s knots at
#: 200 Hz, or 256 for 0.5 s knots, in either stream of the gyro-aided fit).
SPARSE_CHUNK_SAMPLES = (1024, 2048)

# (params, model output, chunk times) → (k, 3, n) extra columns at those times; a callback
# with a ``size`` attribute (k) has its columns written straight after the free ones, and
# one that also ``fills`` writes them there itself (keyword ``into``: the quadrature's).
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
    spline = _spline_of(layout)
    if spline is None or spline.size < 8 or t_s.size < 2:
        return chunk or CHUNK_SAMPLES, False
    rate = (t_s.size - 1) / max(float(t_s[-1] - t_s[0]), 1e-12)
    lo, hi = SPARSE_CHUNK_SAMPLES
    return chunk or min(max(lo, int(2 * spline.spacing_s * rate)), hi), True


def _spline_of(layout: ParameterLayout):
    return next((e for e in layout.effects if e.name == "spin_spline"), None)


@dataclass(frozen=True, eq=False)
class LocalView:
    """A chunk's view of a layout with a spline: only the basis functions alive there.

    Over a few knot intervals all but a handful of the spline's basis functions
    are zero, so the chunk is evaluated with a layout that holds only those
    (``layout``, ``params``); ``index`` maps its rows to the full layout's.
    """

    layout: ParameterLayout
    params: CalibrationParams
    index: np.ndarray


def local_view(
    params: CalibrationParams, layout: ParameterLayout, t_lo: float, t_hi: float
) -> LocalView:
    """The view of ``layout`` on [t_lo, t_hi] (see :class:`LocalView`)."""
    spline = _spline_of(layout)
    active = spline.active(t_lo, t_hi)
    sub = spline.restricted(active)
    effects = tuple(sub if e is spline else e for e in layout.effects)
    local = dataclasses.replace(layout, effects=effects)
    values = params.effect(spline.name, spline.size)
    local_params = params.with_changes(
        effects={**params.effects, spline.name: values[active.start : active.stop]}
    )
    position = {name: i for i, name in enumerate(layout.names)}
    index = np.array([position[name] for name in local.names])
    return LocalView(local, local_params, index)


def effect_priors(
    params: CalibrationParams, layout: ParameterLayout
) -> tuple[float, np.ndarray, np.ndarray] | None:
    """The effects' Gaussian priors: cost Σ (x − μ)²/σ², gradient (x − μ)/σ², information 1/σ².

    An effect whose ``prior_std_values()`` is not None (σ per parameter, ∞ for none)
    — e.g. a gyro's sensitivity to acceleration of its sensor class — adds them once
    per stream, as pseudo-observations around ``prior_mean_values()``; gradient and
    information are over the layout.
    """
    found = False
    cost, grad, info = 0.0, np.zeros(layout.size), np.zeros(layout.size)
    for effect in layout.effects:
        std = effect.prior_std_values()
        if std is None:
            continue
        found = True
        block = layout.blocks[f"effect:{effect.name}"]
        x = np.asarray(params.effect(effect.name, effect.size), dtype=float)
        x = x - effect.prior_mean_values()
        weight = 1.0 / np.asarray(std, dtype=float) ** 2
        cost += float(np.sum(weight * x * x))
        grad[block] += weight * x
        info[block] += weight
    return (cost, grad, info) if found else None


def _with_priors(
    normal: NormalEquations, params: CalibrationParams, layout: ParameterLayout
) -> NormalEquations:
    prior = effect_priors(params, layout)
    if prior is None:
        return normal
    cost, grad, info = prior
    hess, gradient = normal.hessian, normal.gradient
    if gradient is not None:
        gradient = gradient.copy()
        gradient[: layout.size] += grad
    if hess is not None:
        hess = hess.copy()
        index = np.arange(layout.size)
        hess[index, index] += info
    return NormalEquations(normal.cost + cost, hess, gradient, normal.entries)


def accumulate(
    params: CalibrationParams,
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    layout: ParameterLayout,
    noise: NoiseModel,
    jacobian: bool = True,
    extra: ExtraColumns | None = None,
    chunk: int | None = None,
    evaluated: Sequence[ModelOutput] | None = None,
) -> NormalEquations:
    """Accumulate cost, J̃ᵀJ̃ and J̃ᵀr̃ of the whitened residual (model − data).

    With a local basis in the layout (a wheel-angle spline), chunks follow its
    knots and the Gram products skip the rows that are zero over a chunk.
    ``evaluated``: the model with its Jacobian at ``params``, one per chunk (each
    with its p samples of history, as here), when the caller has it (a
    :func:`gradient_pass` there formed it, a dense layout): its J serves, the same
    numbers without a second evaluation.
    """
    n = t_s.size
    chunk, sparse = chunking(layout, t_s, chunk)
    p = noise.order
    if evaluated is not None:
        sizes = [min(n, start + chunk) - max(0, start - p) for start in range(0, n, chunk)]
        got = [output.predicted_mps2.shape[0] for output in evaluated]
        if sparse or not jacobian or got != sizes:
            raise ValueError("evaluated Jacobians serve a dense layout's chunks, one each")
    cost = 0.0
    entries = 0
    hess = grad = None
    # Learnt from the first chunk, unless the callback states it (then no copy at all).
    extra_size = getattr(extra, "size", None) if extra is not None else None
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        lo = max(0, start - p)  # p samples of history for the FIR whitening
        if not jacobian:
            out = evaluate(params, t_s[lo:stop], layout)
            rw, _ = noise.whiten(out.predicted_mps2 - accel_mps2[lo:stop])
            cost += float(np.sum(rw * rw))
            entries += rw.size
            continue
        view = local_view(params, layout, t_s[lo], t_s[stop - 1]) if sparse else None
        here, at = (view.layout, view.params) if view else (layout, params)
        formed = None if evaluated is None else evaluated[start // chunk]
        buf, residual, extra_size = _filled_buffer(
            at, t_s[lo:stop], accel_mps2[lo:stop], here, extra, extra_size, evaluated=formed
        )
        gram, rows = _whitened_gram(buf, residual, noise)
        if hess is None:
            total = layout.size + (extra_size or 0)
            hess, grad = np.zeros((total, total)), np.zeros(total)
        if view is None:
            hess += gram[:-1, :-1]
            grad += gram[:-1, -1]
        else:
            index = np.concatenate([view.index, layout.size + np.arange(extra_size or 0)])
            hess[np.ix_(index, index)] += gram[:-1, :-1]
            grad[index] += gram[:-1, -1]
        cost += float(gram[-1, -1])
        entries += rows
    normal = NormalEquations(cost=cost, hessian=hess, gradient=grad, entries=entries)
    return _with_priors(normal, params, layout)


def _filled_buffer(
    params: CalibrationParams,
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    layout: ParameterLayout,
    extra: ExtraColumns | None,
    extra_size: int | None,
    output: ModelOutput | None = None,
    evaluated: ModelOutput | None = None,
) -> tuple[np.ndarray, np.ndarray, int | None]:
    """[J | extra columns | residual] (P + k + 1, 3, n), the residual (model − data), k.

    One buffer for the free parameters' columns, the extra ones and the residual:
    one whitening, and one Gram product gives H, g and the cost together (a second
    pass over J̃ for g costs more than the Gram's extra row).  ``extra_size`` None:
    learnt from the callback's first columns (then one copy).  ``output``: the
    model already evaluated there (the paper's model), whose Jacobian alone is formed.
    ``evaluated``: the model with its Jacobian already evaluated there (copied in).
    """
    buf = np.empty((layout.size + (extra_size or 0) + 1, 3, t_s.size))
    if evaluated is not None:
        out = evaluated
        buf[: layout.size] = evaluated.jacobian
    else:
        out = evaluate(params, t_s, layout, jacobian=True, out=buf[: layout.size], output=output)
    residual = out.predicted_mps2 - accel_mps2
    if extra is not None:
        cols = extra(params, out, t_s)
        if extra_size is None:
            extra_size = cols.shape[0]
            buf = np.concatenate([buf[: layout.size], cols, buf[-1:]])
        else:
            buf[layout.size : -1] = cols
    buf[-1] = residual.T
    return buf, residual, extra_size


def _whitened_gram(
    buf: np.ndarray, residual: np.ndarray, noise: NoiseModel
) -> tuple[np.ndarray, int]:
    """The Gram matrix of the whitened buffer, and the whitened residual entries."""
    # Not in place: for white noise one batched 3×3 product beats six scaled adds.
    _, jw = noise.whiten(residual, buf)
    jt = jw.reshape(jw.shape[0], -1)
    return jt @ jt.T, jw.shape[1] * jw.shape[2]


def accumulate_fitting_noise(
    params: CalibrationParams,
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    layout: ParameterLayout,
    noise_of: Callable[[np.ndarray], NoiseModel],
    extra: ExtraColumns | None = None,
) -> tuple[NormalEquations, NoiseModel]:
    """The noise model of the residual at ``params``, and its whitened normal equations.

    ``noise_of`` takes the residual (data − model, (N, 3)).  The joint fit's
    stage 2 needs both at its start.  For the paper's model the residual comes
    first (the model without its Jacobian), then the cost and g over every
    sample by :func:`gradient_pass` (g of the free parameters only: no extra
    rows), and H by quadrature on a fraction of the rows
    (:mod:`wheelcal.estimate.joint.fisher_quadrature`) when the wheel turns slowly
    enough for it; otherwise H and g are :func:`accumulate`'s (for a window of
    one chunk from one evaluation of the model, its Jacobian kept until the
    noise is known).  With effects: one chunk only.
    """
    one_chunk = t_s.size <= CHUNK_SAMPLES
    if chunking(layout, t_s, None)[1] or (layout.effects and not one_chunk):
        raise ValueError("accumulate_fitting_noise takes a dense layout (with effects: one chunk)")
    extra_size = getattr(extra, "size", None) if extra is not None else None
    if layout.effects:  # J̃ᵀr̃ without J (gradient_pass) covers the paper's model only
        buf, residual, extra_size = _filled_buffer(
            params, t_s, accel_mps2, layout, extra, extra_size
        )
        noise = noise_of(np.negative(residual))
        # With the effects' priors, as accumulate has them: without, stage 2 started
        # from a Hessian that left a gyro's G free (a step of 10³ σ along it) and a cost
        # Σ (x/σ)² below every later pass's, so that no step could lower it ("stalled").
        return _with_priors(_whitened_normal(buf, residual, noise), params, layout), noise
    output = None
    if one_chunk:
        output = evaluate(params, t_s, layout)
        noise = noise_of(np.subtract(accel_mps2, output.predicted_mps2))
    else:
        noise = noise_of(residual_of(params, t_s, accel_mps2, layout))
    stride = stride_for(t_s, params.spin, noise.order)
    if stride == 1:
        if not one_chunk:
            return accumulate(params, t_s, accel_mps2, layout, noise, extra=extra), noise
        buf, residual, extra_size = _filled_buffer(
            params, t_s, accel_mps2, layout, extra, extra_size, output=output
        )
        return _whitened_normal(buf, residual, noise), noise
    normal = gradient_pass(params, t_s, accel_mps2, layout, noise, output=output)
    rows = quadrature_rows(t_s.size, noise.order, stride)
    hessian = quadrature_hessian(params, t_s, layout, noise, rows, extra, output)
    return dataclasses.replace(normal, hessian=hessian), noise


def residual_of(
    params: CalibrationParams, tc: np.ndarray, v: np.ndarray, layout: ParameterLayout
) -> np.ndarray:
    """The residual (data − model, shape (N, 3)), the model evaluated in chunks.

    The model's temporaries (ϑ, ω, sin ϑ, cos ϑ, a, s …: ~150 B per sample at
    once) stay bounded; only the residual itself grows with N.
    """
    residual = np.empty_like(v, dtype=float)
    for start in range(0, tc.size, CHUNK_SAMPLES):
        stop = min(tc.size, start + CHUNK_SAMPLES)
        part = residual[start:stop]
        np.subtract(
            v[start:stop], evaluate(params, tc[start:stop], layout).predicted_mps2, out=part
        )
    return residual


def _whitened_normal(buf: np.ndarray, residual: np.ndarray, noise: NoiseModel) -> NormalEquations:
    gram, rows = _whitened_gram(buf, residual, noise)
    return NormalEquations(
        cost=float(gram[-1, -1]),
        hessian=gram[:-1, :-1].copy(),
        gradient=gram[:-1, -1].copy(),
        entries=rows,
    )


def quadrature_hessian(
    params: CalibrationParams,
    t_s: np.ndarray,
    layout: ParameterLayout,
    noise: NoiseModel,
    rows: QuadratureRows,
    extra: ExtraColumns | None = None,
    output: ModelOutput | None = None,
) -> np.ndarray:
    """J̃ᵀJ̃ over [free | extra] by the quadrature ``rows`` (the model at their clusters only).

    The clusters are evaluated at most :data:`CHUNK_SAMPLES` samples at a time.
    ``output``: the paper's model (no Jacobian) at ``params`` over all of ``t_s``, when
    the caller has it: its ϑ, ω, ω̇, force and prediction at the clusters then serve.
    """
    extra_size = getattr(extra, "size", None) if extra is not None else 0
    gram = None
    for part in rows.batches(CHUNK_SAMPLES):
        samples = part.samples  # (p + 1, n)
        index = samples.reshape(-1)
        t = t_s[index]
        buf = np.empty((layout.size + (extra_size or 0), 3, t.size))
        there = None if output is None else output_at_samples(output, index)
        out = evaluate(params, t, layout, jacobian=True, out=buf[: layout.size], output=there)
        if extra is not None and extra_size and getattr(extra, "fills", False):
            extra(params, out, t, into=buf[layout.size :])
        elif extra is not None:
            cols = extra(params, out, t)
            if extra_size is None:
                buf = np.concatenate([buf[: layout.size], cols])
            else:
                buf[layout.size :] = cols
        white = whitened_rows(noise, buf.reshape(buf.shape[0], 3, *samples.shape))
        factor = part.weigh(white)
        flat = white.reshape(white.shape[0], -1)
        here = flat @ flat.T
        here *= factor
        gram = here if gram is None else gram + here
    return gram


def gradient_pass(
    params: CalibrationParams,
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    layout: ParameterLayout,
    noise: NoiseModel,
    chunk: int | None = None,
    residual_out: np.ndarray | None = None,
    output: ModelOutput | None = None,
    reverse_out: list | None = None,
    evaluated_out: list | None = None,
) -> NormalEquations:
    """Cost and g = J̃ᵀr̃ without H: the whitening applied to the residual, not to J.

    With r̃ = W r and J̃ = W J (W = L⁻¹ F: the per-axis FIR F, then L⁻¹),
    g = Jᵀ u with u = Wᵀ r̃ = Fᵀ L⁻ᵀ r̃: three rows are filtered (forwards, then
    backwards) instead of every column of J, and Jᵀ u is taken in reverse mode
    through the model (:func:`~wheelcal.model.forward.jacobian_transpose_times`,
    no J at all; a layout with effects forms J and one matrix–vector product).
    Exact: the sums of :func:`accumulate`, to round-off.  Each chunk's outputs
    reach back over its p samples of history, whose model is evaluated with the
    chunk; so the chunks' sums add up to the whole.  ``residual_out`` (N, 3), when
    given, receives the residual data − model.  ``output``: the model (no Jacobian)
    at ``params`` over all of ``t_s`` when the caller has evaluated it (the paper's
    model, one chunk).  ``reverse_out``, when given with ``output``, receives the pass's
    :class:`~wheelcal.model.forward.ReverseAt` (u, the sums and the wheel angle's
    adjoint rows: what a score test at ``params`` needs again).  ``evaluated_out``, when
    given, receives the model with its Jacobian of each chunk where the pass forms them
    (a layout with effects): :func:`accumulate` at ``params`` takes them.
    """
    n = t_s.size
    chunk, sparse = chunking(layout, t_s, chunk)
    if sparse:
        raise ValueError("gradient_pass does not take a layout with a local basis")
    p = noise.order
    # L⁻ᵀ of the noise model's Σ_e = L Lᵀ (3 × 3: its inverse once, then products).
    inv_chol_t = np.linalg.inv(np.linalg.cholesky(noise.innovation_cov)).T
    reverse = not layout.effects
    if output is not None and (n > chunk or not reverse):
        raise ValueError("an evaluated output serves one chunk of the paper's model")
    cost = 0.0
    entries = 0
    grad = np.zeros(layout.size)
    for start in range(0, n, chunk):
        stop = min(n, start + chunk)
        lo = max(0, start - p)
        if output is None:
            out = evaluate(params, t_s[lo:stop], layout, jacobian=not reverse)
        else:
            out = output
        residual = out.predicted_mps2 - accel_mps2[lo:stop]
        if residual_out is not None:
            np.negative(residual[start - lo :], out=residual_out[start:stop])
        rw, u = whitened_back(residual, noise, inv_chol_t)
        cost += float(np.sum(rw * rw))
        entries += rw.size
        if reverse:
            base, adjoint = reverse_pass(params, t_s[lo:stop], layout, u, out)
            grad += base
            if reverse_out is not None and output is not None:
                reverse_out.append(ReverseAt(u, base, adjoint, (noise, accel_mps2)))
        else:
            grad += out.jacobian.reshape(layout.size, -1) @ u.reshape(-1)
            if evaluated_out is not None:
                evaluated_out.append(out)
    normal = NormalEquations(cost=cost, hessian=None, gradient=grad, entries=entries)
    return _with_priors(normal, params, layout)


def whitened_back(
    residual: np.ndarray, noise: NoiseModel, inv_chol_t: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """r̃ = W r (3, N − p) and u = Wᵀ r̃ (3, N) of a residual (N, 3): g = Jᵀu for any J.

    W = L⁻¹ F (the per-axis FIR F, then L⁻¹), so Wᵀ r̃ = Fᵀ L⁻ᵀ r̃.
    ``inv_chol_t``: L⁻ᵀ, when the caller has it already.
    """
    p = noise.order
    if inv_chol_t is None:
        inv_chol_t = np.linalg.inv(np.linalg.cholesky(noise.innovation_cov)).T
    rw, _ = noise.whiten(residual)
    # Fᵀ L⁻ᵀ r̃: output m of the FIR sums input m + p − k with weight a_k (zero history),
    # so input j receives Σ_k a_k y[j − p + k]; y is padded with p zeros each side.
    m = residual.shape[0]
    padded = np.zeros((3, m + p))
    np.matmul(inv_chol_t, rw, out=padded[:, p:m])
    u = np.empty((3, m))
    for i, a in enumerate(noise.ar_polynomials):
        np.multiply(padded[i, :m], a[0], out=u[i])
        for k in range(1, a.size):
            u[i] += a[k] * padded[i, k : k + m]
    return rw, u


def whitened_cost(residual: np.ndarray, noise: NoiseModel, chunk: int = CHUNK_SAMPLES) -> float:
    """‖r̃‖² of a residual (N, 3) already evaluated, whitened in chunks as :func:`accumulate`.

    The residual's sign does not matter (data − model or model − data).
    """
    p = noise.order
    cost = 0.0
    for start in range(0, residual.shape[0], chunk):
        stop = min(residual.shape[0], start + chunk)
        rw, _ = noise.whiten(residual[max(0, start - p) : stop])
        cost += float(np.sum(rw * rw))
    return cost


def add_gram(
    hess: np.ndarray, grad: np.ndarray, jt: np.ndarray, r: np.ndarray, index: np.ndarray
) -> None:
    """Add J Jᵀ and J r of a chunk's rows to the rows ``index`` of ``hess`` and ``grad``."""
    hess[np.ix_(index, index)] += jt @ jt.T
    grad[index] += jt @ r
