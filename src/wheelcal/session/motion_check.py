"""Whether the fitted spin law describes the wheel's motion well enough to trust the sensor.

Eq. (2) holds for a free spin: ω(t) smooth and slowly decaying.  A driven
wheel (a motor's speed changes, a second push), a very long spin, or any
motion the cubic cannot follow leaves a misfit the joint fit trades into the
sensor's parameters — a confident wrong answer.

The alternative is a smooth correction of the wheel angle,
Δϑ(t) = Σ c_k B_k(t) (:class:`~wheelcal.model.effects.SpinSpline`, knots every
few seconds).  At the fit, one Gauss–Newton step of the extended model gives
what freeing the motion would change:

* the score statistic of the spline coefficients (χ² with their rank as dof);
* the shift Δ of every gain and offset, and — Hausman's test — its own σ,
  √(σ²_flexible − σ²_cubic), since under a correct cubic the two estimates
  differ only by noise.

The motion is *not described* when the shift is both significant
(|Δ| > ``z_limit`` × its σ) and material (|Δ| > ``material_sigma`` × the
cubic fit's σ): the sensor's numbers depend on the motion law.  A once-per-turn
wobble (imbalance) is far faster than the knots and stays out of the test.

The noise model is the fit's AR colour, rescaled per axis to the residual's
*broadband* level (:mod:`wheelcal.session.noise_reference`): an AR model
fitted to the whole residual absorbs the very misfit being tested for.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy import special

from wheelcal.estimate.joint import (
    CHUNK_SAMPLES,
    CalibrationResult,
    FreedCheck,
    NoiseModel,
    quadrature_rows,
    scaled_pinv,
    stride_for,
)
from wheelcal.model import (
    AXES,
    EvaluatedModel,
    SpinSpline,
    cubic_bspline_slots,
    evaluate,
    spin_columns,
)
from wheelcal.session.motion_quadrature import normal_by_quadrature

#: Knots of the alternative motion, and the fewest turns between two of them.
KNOT_SPACING_S = 5.0
MAX_KNOTS = 40


@dataclass(frozen=True)
class MotionCheck(FreedCheck):
    """What freeing the motion (a spline of ϑ) would change (``fit.motion_check``)."""

    ALTERNATIVE: ClassVar[str] = "cubic B-spline correction of the wheel angle"

    def inadequate(self, z_limit: float, material_sigma: float) -> bool:
        """True when some gain or offset moves significantly and materially."""
        return bool(self.moved(z_limit, material_sigma))

    def worst(self) -> str:
        """The gain/offset that moves most, as text."""
        name = max(self.shift_sigma, key=self.shift_sigma.get)
        return f"{name} by {self.shift_sigma[name]:.1f} σ (z = {self.shift_z[name]:.1f})"


def broadband_noise(noise: NoiseModel, broadband_mps2: np.ndarray) -> NoiseModel:
    """``noise`` with its per-axis level set to ``broadband_mps2`` (colour kept)."""
    scale = np.asarray(broadband_mps2, dtype=float) / np.maximum(noise.marginal_std_mps2, 1e-30)
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
    return NoiseModel(noise.ar_polynomials, noise.innovation_cov * np.outer(scale, scale))


#: Singular values of the normalised Schur complement below this × the largest are null.
RANK_RTOL = 1e-10


def _normal_with_spline(
    result: CalibrationResult,
    accel_mps2: np.ndarray,
    noise: NoiseModel,
    spline: SpinSpline,
    evaluated: EvaluatedModel | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """H = J̃ᵀJ̃ and g = J̃ᵀr̃ over [the fit's parameters | the spline's coefficients].

    For the paper's model, H by quadrature and g without a Jacobian
    (:mod:`~wheelcal.session.motion_quadrature`) when the wheel turns slowly enough for the
    rule (:func:`~wheelcal.estimate.joint.fisher_quadrature.stride_for`); otherwise the sums
    by parts over every sample below.  One pass over the samples in chunks
    (:data:`CHUNK_SAMPLES`, FIR history carried as in
    :func:`~wheelcal.estimate.joint.normal_equations.accumulate`) evaluates the
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


def check_motion(
    result: CalibrationResult,
    accel_mps2: np.ndarray,
    noise: NoiseModel,
    spacing_s: float = KNOT_SPACING_S,
    evaluated: EvaluatedModel | None = None,
) -> MotionCheck | None:
    """Score and Hausman test of a spline motion at ``result`` (None: window too short).

    ``evaluated``: the model at the result as the fit's last pass left it
    (:meth:`~wheelcal.estimate.joint.fit.JointFit.fit_evaluated`), to save evaluating it again.
    """
    tc = result.centred_time_s
    span = float(tc[-1] - tc[0])
    spacing = max(spacing_s, span / MAX_KNOTS)
    if span < 2 * spacing:
        return None
    spline = SpinSpline(float(tc[0]), float(tc[-1]), spacing)
    layout = result.layout
    h, g = _normal_with_spline(result, accel_mps2, noise, spline, evaluated)
    size = layout.size
    h_bb_inv = scaled_pinv(h[:size, :size])
    h_inv = scaled_pinv(h)
    # Score test of the spline coefficients (Schur complement of the base block).
    h_eb = h[size:, :size]
    schur = h[size:, size:] - h_eb @ h_bb_inv @ h_eb.T
    u = g[size:] - h_eb @ h_bb_inv @ g[:size]
    c_inv = scaled_pinv(schur)
    statistic = float(u @ c_inv @ u)
    # The spline spans the cubic's own directions: those leave singular values at the
    # round-off level (1e-14 of the largest), which a default-tolerance rank counted
    # or not at random; the directions the data do determine stay above 1e-10.
    normalised = schur / np.sqrt(np.outer(np.diag(schur), np.diag(schur)))
    singular = np.linalg.svd(normalised, compute_uv=False)
    dof = int(np.sum(singular > RANK_RTOL * singular[0]))
    # The χ² survival function (what stats.chi2.sf returns, without its ~40 µs of checks).
    p_value = float(special.chdtrc(max(dof, 1), statistic))
    # The sensor parameters' shift when the motion is freed (one Gauss–Newton step),
    # net of the base model's own (tiny) step under this noise model.
    shift = -(h_inv @ g)[:size] + h_bb_inv @ g[:size]
    blocks = layout.blocks
    index = list(range(blocks["gain"].start, blocks["offset"].stop))
    names = [f"gain_{a}" for a in AXES] + [f"offset_{a}_mps2" for a in AXES]
    var_cubic = np.diag(h_bb_inv)[index]
    var_flexible = np.diag(h_inv)[index]
    extra_std = np.sqrt(np.maximum(var_flexible - var_cubic, 1e-300))
    delta = np.abs(shift[index])
    return MotionCheck(
        statistic=statistic,
        dof=dof,
        p_value=p_value,
        shift_sigma=dict(zip(names, (delta / np.sqrt(var_cubic)).tolist(), strict=True)),
        shift_z=dict(zip(names, (delta / extra_std).tolist(), strict=True)),
        spacing_s=spacing,
    )
