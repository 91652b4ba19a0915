"""The normal equations over [a fit's parameters | a spline of the wheel angle ϑ].

A freed motion (the session's motion check, :func:`wheelcal.session.motion_check.check_motion`)
asks what a smooth correction of the wheel angle, Δϑ(t) = Σ c_k B_k(t)
(:class:`~wheelcal.model.effects.SpinSpline`), would change at the fit: that needs
H = J̃ᵀJ̃ and g = J̃ᵀr̃ over the fit's parameters and the spline's coefficients,
which :func:`normal_with_spline` sums — by quadrature for the paper's model
(:mod:`.spline_quadrature`), by parts over every sample otherwise.  The estimator's
chunk size, quadrature rule and whitening stay behind this one function.
"""

from __future__ import annotations

import itertools

import numpy as np

from wheelcal.estimate.joint.fisher_quadrature import quadrature_rows, stride_for
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.normal_equations import CHUNK_SAMPLES
from wheelcal.estimate.joint.result import CalibrationResult
from wheelcal.estimate.joint.spline_quadrature import normal_by_quadrature
from wheelcal.model import (
    EvaluatedModel,
    SpinSpline,
    cubic_bspline_slots,
    evaluate,
    spin_columns,
)


def normal_with_spline(
    result: CalibrationResult,
    accel_mps2: np.ndarray,
    noise: NoiseModel,
    spline: SpinSpline,
    evaluated: EvaluatedModel | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """H = J̃ᵀJ̃ and g = J̃ᵀr̃ over [the fit's parameters | the spline's coefficients].

    For the paper's model, H by quadrature and g without a Jacobian
    (:mod:`.spline_quadrature`) when the wheel turns slowly enough for the
    rule (:func:`~.fisher_quadrature.stride_for`); otherwise the sums
    by parts over every sample below.  One pass over the samples in chunks
    (:data:`CHUNK_SAMPLES`, FIR history carried as in
    :func:`~.normal_equations.accumulate`) evaluates the
    model and its Jacobian once.  A coefficient c_k acts on the wheel angle alone (Δϑ = B_k, Δω
    = B_k′, Δω̇ = B_k″), and in knot interval j only B_j … B_{j+3} are not zero: each sample's
    four *slot* columns (its interval's functions, :func:`~wheelcal.model.forward.spin_columns`)
    are computed once and whitened with the base columns.  Whitening a slot row treats its
    history as the same functions' when it lies in the interval before;
    :func:`_add_slot_corrections` adds what the FIR history truly holds there (the next slot's
    column: that interval numbers its functions from one lower), and the function before the
    interval (B_{j−1}), which only that history reaches.  Their Gram blocks with the base
    columns and with each other are then added per interval by small products.  The sums are
    those of one dense accumulation over every coefficient, to round-off.
    ``evaluated``: the model at the result without a Jacobian (the fit's last
    pass); a chunk it covers forms only the Jacobian from it.
    """
    if spline.first != 0:
        raise ValueError("the motion check's spline must span the whole window")
    tc = result.centred_time_s
    layout = result.layout
    params = result.params
    size = layout.size
    p = noise.order
    if not layout.effects:  # J̃ᵀr̃ without J: the paper's model
        stride = stride_for(tc, params.spin, p, spline.spacing_s)
        if stride > 1:
            rows = quadrature_rows(tc.size, p, stride)
            return normal_by_quadrature(result, accel_mps2, noise, spline, rows, evaluated)
    # Three rows past the last function: the last sample's slot 3 (exactly zero there).
    total = size + spline.size + 3
    hess = np.zeros((total, total))
    grad = np.zeros(total)
    for start in range(0, tc.size, CHUNK_SAMPLES):
        stop = min(tc.size, start + CHUNK_SAMPLES)
        lo = max(0, start - p)  # p samples of history; whitening drops p outputs
        t = tc[lo:stop]
        interval, *rows = cubic_bspline_slots(t, spline.start_s, spline.spacing_s)
        steps = np.diff(interval)
        bounds = np.flatnonzero(steps) + 1  # first samples of a new interval
        # The slots whiten with the base columns when any FIR history spans at most one
        # interval boundary (intervals of ≥ p samples, none skipped); else a group of
        # functions is whitened per interval (:func:`_whitened_group`).
        together = p == 0 or (np.all(np.diff(bounds) >= p) and np.all(steps[bounds - 1] == 1))
        # Rows: the base columns, the residual and the four slot columns, all whitened
        # at once; one product per knot interval then gives its rows of H and g.
        buf = np.empty((size + 1 + 4 * together, 3, t.size))
        shared = evaluated.output_at(params, t) if evaluated is not None else None
        out = evaluate(params, t, layout, jacobian=True, out=buf[:size], output=shared)
        residual = out.predicted_mps2 - accel_mps2[lo:stop]
        buf[size] = residual.T
        slots = spin_columns(
            params, t, layout, tuple(rows), out, buf[size + 1 :] if together else None
        )
        _, jw = noise.whiten(residual, buf)  # (white: one batched product, not in place)
        jt = jw[: size + 1].reshape(size + 1, -1)
        gram = jt @ jt.T
        hess[:size, :size] += gram[:size, :size]
        grad[:size] += gram[:size, size]
        if together and p > 0 and bounds.size:
            _add_slot_corrections(hess, grad, jw, slots, interval, bounds, noise, size)
        _add_interval_blocks(hess, grad, jw, slots, interval, noise, size, together)
    keep = size + spline.size
    hess[:size, size:] = hess[size:, :size].T
    return hess[:keep, :keep], grad[:keep]


def _add_interval_blocks(
    hess: np.ndarray,
    grad: np.ndarray,
    jw: np.ndarray,
    slots: np.ndarray,
    interval: np.ndarray,
    noise: NoiseModel,
    size: int,
    together: bool,
) -> None:
    """Add one chunk's spline rows of H and g, knot interval by knot interval.

    ``jw`` holds the whitened base columns and residual, and — ``together`` —
    the four slot columns whitened with them; else each interval's group of
    functions is whitened here from ``slots`` (:func:`_whitened_group`).
    """
    p = noise.order
    cuts = np.flatnonzero(np.diff(interval[p:])) + p + 1
    for a, b in itertools.pairwise([p, *cuts.tolist(), interval.size]):
        jg = jw[:, :, a - p : b - p]
        if together:
            first, sw = int(interval[a]), jg[size + 1 :]
        else:
            first, sw = _whitened_group(interval, slots, noise, a, b)
        cross = sw[:, 0, :] @ jg[:, 0, :].T
        cross += sw[:, 1, :] @ jg[:, 1, :].T
        cross += sw[:, 2, :] @ jg[:, 2, :].T
        rows_here = slice(size + first, size + first + sw.shape[0])
        hess[rows_here, :size] += cross[:, :size]
        grad[rows_here] += cross[:, size]
        if together:
            hess[rows_here, rows_here] += cross[:, size + 1 :]
        else:
            flat = sw.reshape(sw.shape[0], -1)
            hess[rows_here, rows_here] += flat @ flat.T


def _add_slot_corrections(
    hess: np.ndarray,
    grad: np.ndarray,
    jw: np.ndarray,
    slots: np.ndarray,
    interval: np.ndarray,
    bounds: np.ndarray,
    noise: NoiseModel,
    size: int,
) -> None:
    """Correct the whitened slot rows ``jw[size + 1:]`` past each boundary, in place.

    Output t (the first p after a boundary c, interval j) reaches back into
    interval j − 1, where function j + s is that interval's slot s + 1, not
    slot s: its whitened value gains W Σ a_i (slot_{s+1} − slot_s)(t − i) over
    the history before c (W = L⁻¹ after the per-axis FIR).  The function
    j − 1 (slot −1 here, slot 0 there) lives only in that history: its p
    outputs add a row of H and g of their own (function j − 1's products with
    the base columns, the residual, itself and j … j + 3 over those samples).
    Every boundary at once: the differences before each boundary are whitened
    as blocks of 2p samples (p of history, p of zeros), whose last p outputs
    are the corrections.
    """
    p = noise.order
    n = interval.size
    count = bounds.size
    # Slot differences, rows s = −1 … 3: slot_{s+1} − slot_s (slot_{−1} = slot_4 = 0).
    history = bounds[:, None] - p + np.arange(p)  # (boundaries, p) sample indices
    inside = history >= 0
    taken = slots[:, :, np.where(inside, history, 0)]  # (4, 3, boundaries, p)
    taken[:, :, ~inside] = 0.0
    blocks = np.zeros((5, 3, count, 2 * p))
    blocks[0, :, :, :p] = taken[0]
    blocks[1:4, :, :, :p] = taken[1:] - taken[:-1]
    blocks[4, :, :, :p] = -taken[3]
    _, white = noise.whiten(np.zeros((count * 2 * p, 3)), blocks.reshape(5, 3, -1))
    # Block b's outputs at its samples p … 2p − 1 are whitened entries 2pb … 2pb + p − 1.
    outputs = 2 * p * np.arange(count)[:, None] + np.arange(p)
    delta = white[:, :, outputs]  # (5, 3, boundaries, p): at samples bounds + m
    at = bounds[:, None] + np.arange(p)
    valid = (at >= p) & (at < n)  # outputs that exist in this chunk
    delta[:, :, ~valid] = 0.0
    column = np.where(valid, at - p, 0)  # whitened entry of each output
    jw[size + 1 :, :, column[valid]] += delta[1:, :, valid]  # distinct outputs
    # Function j − 1 over those outputs: its products with every whitened row.
    before = delta[0]  # (3, boundaries, p)
    rows_there = jw[:, :, column]  # (size + 5, 3, boundaries, p), slots corrected
    rows_there[:, :, ~valid] = 0.0
    products = np.einsum("xbm,rxbm->br", before, rows_there)
    own = np.einsum("xbm,xbm->b", before, before)
    j = interval[bounds].astype(np.int64)
    row = size + j - 1
    hess[row, :size] += products[:, :size]
    grad[row] += products[:, size]
    block = row[:, None] + 1 + np.arange(4)
    hess[row[:, None], block] += products[:, size + 1 :]
    hess[block, row[:, None]] += products[:, size + 1 :]
    hess[row, row] += own


def _whitened_group(
    interval: np.ndarray, slots: np.ndarray, noise: NoiseModel, a: int, b: int
) -> tuple[int, np.ndarray]:
    """Whitened columns of one knot interval's samples [a, b): (first function, (k, 3, b − a)).

    Every function alive over the FIR history [a − p, b) has a column (the one
    before the interval leaks into its first p outputs).
    """
    h = a - noise.order
    first = int(interval[h])
    count = int(interval[a]) - first + 4
    raw = np.zeros((count, 3, b - h))
    cuts = np.flatnonzero(np.diff(interval[h:b])) + h + 1
    for s, e in itertools.pairwise([h, *cuts.tolist(), b]):
        row = int(interval[s]) - first
        raw[row : row + 4, :, s - h : e - h] = slots[:, :, s:e]
    return first, noise.whiten(np.zeros((b - h, 3)), raw)[1]
