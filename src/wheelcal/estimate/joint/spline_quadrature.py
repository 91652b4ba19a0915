"""The sums over [the fit's parameters | a spline of ϑ] by quadrature.

:func:`~.spline_normal.normal_with_spline` (the session's motion check) needs H = J̃ᵀJ̃ and
g = J̃ᵀr̃ over the fit's parameters and the coefficients of a wheel-angle
spline (:class:`~wheelcal.model.effects.SpinSpline`).  For the paper's model:

* g over every sample, without a Jacobian: the residual whitened back
  (u = Wᵀ W r, three rows), Jᵀu through the model's reverse mode
  (:func:`~wheelcal.model.forward.jacobian_transpose_times`), and each spline
  function's sum from the reverse mode's wheel-angle rows
  (:func:`~wheelcal.model.forward.spin_adjoint`) times its B, B′, B″, summed
  per knot interval.  A chunk at a time, each with its p samples of FIR
  history, as :func:`~wheelcal.estimate.joint.normal_equations.gradient_pass`.
* H by quadrature (:mod:`wheelcal.estimate.joint.fisher_quadrature`): the model, its
  Jacobian and the four slot columns at the kept rows' FIR clusters only.  A
  cluster's samples may lie in two knot intervals, so its columns cover every
  function alive over it (its first sample's interval j … the last's + 3); the
  clusters that start in interval j then add their Gram block with the base
  columns and each other in one product.
"""

from __future__ import annotations

import itertools

import numpy as np

from wheelcal.estimate.joint.fisher_quadrature import QuadratureRows, whitened_rows
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.normal_equations import CHUNK_SAMPLES, whitened_back
from wheelcal.estimate.joint.result import CalibrationResult
from wheelcal.model import (
    EvaluatedModel,
    SpinSpline,
    cubic_bspline_slots,
    evaluate,
    jacobian_transpose_times,
    spin_adjoint,
    spin_columns,
)


def normal_by_quadrature(
    result: CalibrationResult,
    accel_mps2: np.ndarray,
    noise: NoiseModel,
    spline: SpinSpline,
    rows: QuadratureRows,
    evaluated: EvaluatedModel | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(H, g) over [the fit's parameters | the spline's coefficients] (see the module doc).

    ``evaluated``: the model at the result as the fit's last pass left it (one chunk).
    """
    size = result.layout.size
    total = size + spline.size + 3  # three rows past the last function: the last slot 3
    grad = _gradient(result, accel_mps2, noise, spline, evaluated, total)
    hess = _hessian(result, noise, spline, rows, total)
    keep = size + spline.size
    hess[:size, size:] = hess[size:, :size].T
    return hess[:keep, :keep], grad[:keep]


def _gradient(
    result: CalibrationResult,
    accel_mps2: np.ndarray,
    noise: NoiseModel,
    spline: SpinSpline,
    evaluated: EvaluatedModel | None,
    total: int,
) -> np.ndarray:
    tc, layout, params = result.centred_time_s, result.layout, result.params
    size, p = layout.size, noise.order
    grad = np.zeros(total)
    for start in range(0, tc.size, CHUNK_SAMPLES):
        stop = min(tc.size, start + CHUNK_SAMPLES)
        lo = max(0, start - p)  # the outputs' FIR history: evaluated with the chunk
        t = tc[lo:stop]
        output = evaluated.output_at(params, t) if evaluated is not None else None
        if output is None:
            output = evaluate(params, t, layout)
        _, u = whitened_back(output.predicted_mps2 - accel_mps2[lo:stop], noise)
        grad[:size] += jacobian_transpose_times(params, t, layout, u, output)
        # Function j + q of sample n (slot q): Σ_n (B, B′, B″)_{j+q}(t_n) · spin_adjoint_n,
        # summed per knot interval (a run of samples), then placed q functions on.
        interval, *slot_rows = cubic_bspline_slots(t, spline.start_s, spline.spacing_s)
        adjoint = spin_adjoint(params, u, output)
        along = slot_rows[0] * adjoint[0]
        along += slot_rows[1] * adjoint[1]
        along += slot_rows[2] * adjoint[2]
        runs = np.concatenate([[0], np.flatnonzero(np.diff(interval)) + 1])
        sums = np.add.reduceat(along, runs, axis=1)
        function = size + interval[runs].astype(np.intp)
        for q in range(4):
            grad[function + q] += sums[q]
    return grad


def _hessian(
    result: CalibrationResult,
    noise: NoiseModel,
    spline: SpinSpline,
    rows: QuadratureRows,
    total: int,
) -> np.ndarray:
    tc, layout, params = result.centred_time_s, result.layout, result.params
    size = layout.size
    hess = np.zeros((total, total))
    for part in rows.batches(CHUNK_SAMPLES):
        samples = part.samples  # (p + 1, n): the clusters, lag p first
        t = tc[samples.reshape(-1)]
        interval, *slot_rows = cubic_bspline_slots(t, spline.start_s, spline.spacing_s)
        interval = interval.astype(np.intp).reshape(samples.shape)
        shift = interval - interval[0]  # a sample's interval from its cluster's first
        width = int(shift[-1].max()) + 4
        buf = np.zeros((size + width, 3, t.size))
        out = evaluate(params, t, layout, jacobian=True, out=buf[:size])
        # Function interval + q is the cluster's column shift + q: written at shift 0,
        # then the samples past a knot (shift > 0: clusters that straddle one) moved.
        spin_columns(params, t, layout, tuple(slot_rows), out, buf[size : size + 4])
        columns = buf.reshape(size + width, 3, *samples.shape)
        lag, cluster = np.nonzero(shift)
        if lag.size:
            moved = columns[size : size + 4, :, lag, cluster]  # (4, 3, m): a copy
            columns[size:, :, lag, cluster] = 0.0
            for q in range(4):
                columns[size + shift[lag, cluster] + q, :, lag, cluster] = moved[q].T
        white = whitened_rows(noise, columns)  # (rows, n, 3): a run of clusters is a view
        factor = part.weigh(white)
        base = white[:size].reshape(size, -1)
        here = np.zeros_like(hess)
        here[:size, :size] = base @ base.T
        # One product per run of clusters starting in the same interval j (functions
        # j … j + width − 1), then each of the width rows added for every run at once.
        starts = interval[0]
        bounds = [0, *(np.flatnonzero(np.diff(starts)) + 1).tolist(), starts.size]
        first = starts[bounds[:-1]]  # distinct, increasing
        cross = np.empty((first.size, width, size + width))
        for r, (a, b) in enumerate(itertools.pairwise(bounds)):
            block = white[:, a:b, :].reshape(size + width, -1)
            np.matmul(block[size:], block.T, out=cross[r])
        own = size + first[:, None] + np.arange(width)  # (runs, width) rows of H
        for w in range(width):
            here[own[:, w], :size] += cross[:, w, :size]
            here[own[:, w : w + 1], own] += cross[:, w, size:]
        here *= factor
        hess += here
    return hess
