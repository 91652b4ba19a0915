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
*broadband* level (:mod:`wheelcal.estimate.noise_reference`): an AR model
fitted to the whole residual absorbs the very misfit being tested for.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy import stats

from wheelcal.estimate.information import scaled_pinv
from wheelcal.estimate.noise_model import NoiseModel
from wheelcal.estimate.normal_equations import accumulate
from wheelcal.estimate.result import CalibrationResult
from wheelcal.model.effects import SpinSpline, basis_cache_off
from wheelcal.model.forward import candidate_columns
from wheelcal.model.parameters import AXES

#: Knots of the alternative motion, and the fewest turns between two of them.
KNOT_SPACING_S = 5.0
MAX_KNOTS = 40


@dataclass(frozen=True)
class MotionCheck:
    """What freeing the motion (a spline of ϑ) would change in the sensor's parameters."""

    statistic: float  # score χ² of the spline coefficients
    dof: int
    p_value: float
    shift_sigma: dict[str, float]  # |Δ| / σ of the cubic fit, per gain/offset
    shift_z: dict[str, float]  # |Δ| / √(σ²_flexible − σ²_cubic)
    spacing_s: float

    def inadequate(self, z_limit: float, material_sigma: float) -> bool:
        """True when some gain or offset moves significantly and materially."""
        return any(
            self.shift_z[n] > z_limit and self.shift_sigma[n] > material_sigma for n in self.shift_z
        )

    def worst(self) -> str:
        """The gain/offset that moves most, as text."""
        name = max(self.shift_sigma, key=self.shift_sigma.get)
        return f"{name} by {self.shift_sigma[name]:.1f} σ (z = {self.shift_z[name]:.1f})"

    def to_dict(self) -> dict:
        """For the calibration JSON (``fit.motion_check``)."""
        return {
            "alternative": "cubic B-spline correction of the wheel angle",
            "knot_spacing_s": self.spacing_s,
            "statistic": self.statistic,
            "dof": self.dof,
            "p_value": self.p_value,
            "shift_sigma": self.shift_sigma,
            "shift_z": self.shift_z,
        }


def broadband_noise(noise: NoiseModel, broadband_mps2: np.ndarray) -> NoiseModel:
    """``noise`` with its per-axis level set to ``broadband_mps2`` (colour kept)."""
    scale = np.asarray(broadband_mps2, dtype=float) / np.maximum(noise.marginal_std_mps2, 1e-30)
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
    return NoiseModel(noise.ar_polynomials, noise.innovation_cov * np.outer(scale, scale))


#: Singular values of the normalised Schur complement below this × the largest are null.
RANK_RTOL = 1e-10
#: Each accumulation covers whole knot intervals and at least this many samples.
MIN_CHUNK_SAMPLES = 2048


def _normal_with_spline(
    result: CalibrationResult, accel_mps2: np.ndarray, noise: NoiseModel, spline: SpinSpline
) -> tuple[np.ndarray, np.ndarray]:
    """H = J̃ᵀJ̃ and g = J̃ᵀr̃ over [the fit's parameters | the spline's coefficients].

    A cubic B-spline coefficient acts on four knot intervals only, so the
    samples are taken a few intervals at a time with just the coefficients
    alive there as extra columns (6 of ~20 at 200 Hz: a third of the Gram
    product's work).  Each part starts ``noise.order`` samples early for the
    FIR whitening's history, whose outputs it drops: the sums are those of the
    whole series, whitened at once.
    """
    tc = result.centred_time_s
    layout = result.layout
    size = layout.size
    n = tc.size
    rate = (n - 1) / max(float(tc[-1] - tc[0]), 1e-12)
    per = max(1, int(np.ceil(MIN_CHUNK_SAMPLES / (spline.spacing_s * rate))))
    step_s = spline.spacing_s * per
    edges = spline.start_s + step_s * np.arange(1, int(np.ceil((tc[-1] - tc[0]) / step_s)))
    edges = edges[edges < tc[-1] - 0.5 * step_s]  # no short last part
    bounds = [0, *np.searchsorted(tc, edges, side="left").tolist(), n]
    hess = np.zeros((size + spline.size, size + spline.size))
    grad = np.zeros(size + spline.size)
    for start, stop in itertools.pairwise(bounds):
        if stop <= start:
            continue
        lo = max(0, start - noise.order)
        active = spline.active(float(tc[lo]), float(tc[stop - 1]))
        local = spline.restricted(active)

        def extra(params, output, t_s, local=local):
            return candidate_columns(params, t_s, layout, local, output)

        extra.size = local.size  # columns written in place (see accumulate)
        part = accumulate(
            result.params, tc[lo:stop], accel_mps2[lo:stop], layout, noise, extra=extra
        )
        index = np.concatenate([np.arange(size), size + np.arange(active.start, active.stop)])
        hess[np.ix_(index, index)] += part.hessian
        grad[index] += part.gradient
    return hess, grad


def check_motion(
    result: CalibrationResult,
    accel_mps2: np.ndarray,
    noise: NoiseModel,
    spacing_s: float = KNOT_SPACING_S,
) -> MotionCheck | None:
    """Score and Hausman test of a spline motion at ``result`` (None: window too short)."""
    tc = result.centred_time_s
    span = float(tc[-1] - tc[0])
    spacing = max(spacing_s, span / MAX_KNOTS)
    if span < 2 * spacing:
        return None
    spline = SpinSpline(float(tc[0]), float(tc[-1]), spacing)
    layout = result.layout
    with basis_cache_off():  # every part is visited once
        h, g = _normal_with_spline(result, accel_mps2, noise, spline)
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
    p_value = float(stats.chi2.sf(statistic, max(dof, 1)))
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
