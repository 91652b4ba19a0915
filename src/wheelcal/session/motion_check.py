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

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy import special

from wheelcal.estimate.joint import (
    CalibrationResult,
    FreedCheck,
    NoiseModel,
    normal_with_spline,
    scaled_pinv,
)
from wheelcal.model import AXES, EvaluatedModel, SpinSpline

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
    h, g = normal_with_spline(result, accel_mps2, noise, spline, evaluated)
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
