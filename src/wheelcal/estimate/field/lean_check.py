"""What a camber the model does not follow would move: the field fit's lean check.

The field fit takes the wheel's camber as one number, or as the track the gyro
measures (:mod:`wheelcal.model.rolling`).  Either may be wrong — a roll the gyro
does not see (a wheel steered at a standstill), a gyro's error the track's basis
does not hold, a road whose camber changes faster than the track's band — and
where it is, the axle axis's share of gravity, g sin γ(t), is not what the model
says.  The alternative is a free correction of the camber, Δγ(t) = Σ c_k B_k(t)
(uniform cubic B-splines, knots every ``KNOT_SPACING_S``), on top of the fit's own.
At the fit, one Gauss–Newton step of the extended model gives, as the motion check
does for the wheel angle (:mod:`wheelcal.session.motion_check`):

* the score statistic of the spline coefficients (χ² with their rank as dof);
* the shift Δ of every gain, offset and the radius, and — Hausman's test — its own σ,
  √(σ²_free − σ²_fit), since under a camber the model follows the two estimates
  differ only by noise.

A parameter *moves* when the shift is both significant (|Δ| > ``z_limit`` × its σ)
and material (|Δ| > ``material_sigma`` × the fit's σ).  Both the shift's σ and the
fit's are the sandwich's (the reported σ's kind), not the noise model's.  That is what the camber's
change does to the answer — not its size: a road's 6° that the gyro's track follows
moves nothing; a fraction of a degree it misses may move the axle axis's gain.  H
and g come from the robust pass's evaluation of the model
(:func:`~wheelcal.estimate.field.robust.robust_result_with`), in the fit's noise
model.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy import special

from wheelcal.estimate.field.robust import Extension, WideNormal
from wheelcal.estimate.joint import CalibrationResult, FreedCheck, scaled_pinv
from wheelcal.model import GAIN_NAMES, OFFSET_NAMES, Rolling, cubic_bspline_basis

#: Knots of the free camber (s): a road's camber changes over tens of metres.
KNOT_SPACING_S = 10.0
#: At most this many knot intervals (a long drive's knots are spaced wider).
MAX_INTERVALS = 30
#: The parameters whose shift the check reports.
CHECKED = (*GAIN_NAMES, *OFFSET_NAMES, "radius_m")
#: Singular values of the normalised Schur complement below this × the largest are null.
RANK_RTOL = 1e-10


@dataclass(frozen=True)
class LeanCheck(FreedCheck):
    """What freeing the camber (a spline Δγ(t)) would change (``bench.lean.check``)."""

    ALTERNATIVE: ClassVar[str] = "cubic B-spline correction of the camber"


def camber_extension(result: CalibrationResult, spacing_s: float = KNOT_SPACING_S):
    """The fit's model with the free camber added (:class:`Extension`), or None.

    None when the model has no rolling wheel or the window is shorter than two knot
    intervals.
    """
    layout, params = result.layout, result.params
    rolling = next((e for e in layout.effects if isinstance(e, Rolling)), None)
    tc = result.centred_time_s
    span = float(tc[-1] - tc[0])
    if rolling is None or span < 2 * spacing_s:
        return None
    intervals = min(MAX_INTERVALS, int(np.ceil(span / spacing_s)))
    spacing = span / intervals
    count = intervals + 3
    # the effect's own grid (its series are interpolated onto the evaluated times)
    grid = rolling.time_s
    basis, _, _ = cubic_bspline_basis(grid, float(tc[0]), spacing, count)
    basis = _beyond(basis, rolling)
    if basis.shape[0] == 0:
        return None
    count = basis.shape[0]
    extra = {f"spline_{k}": basis[k] for k in range(count)}
    wider = rolling.with_camber_basis(extra)
    effects = tuple(wider if e is rolling else e for e in layout.effects)
    wide_layout = type(layout)(layout.spin_degree, layout.fit_tilt, layout.fit_radius, effects)
    values = np.concatenate([params.effect(rolling.name, rolling.size), np.zeros(count)])
    wide_params = params.with_changes(effects={**params.effects, rolling.name: values})
    names = list(wide_layout.names)
    index = np.array([names.index(n) for n in layout.names])
    return Extension(wide_params, wide_layout, index), spacing


#: A spline direction whose part beyond the model's own camber shapes is below this
#: fraction of the largest is dropped (it is one the model has already).
BEYOND_RTOL = 1e-3


def _beyond(basis: np.ndarray, rolling: Rolling) -> np.ndarray:
    """The spline's directions the model's camber cannot already take (rows, orthonormal).

    The splines span a constant (the tilt), a ramp (the drift the gyro's errors leave) and
    much of the track's basis: those directions are the fit's own, and left in they make
    the wider model all but singular (a step of ±80° along a ramp the drift term nearly
    holds).  The splines are made orthogonal to [1, l, N_k] over the grid, and to each
    other; what remains is what a camber free to move adds.
    """
    own = [np.ones(basis.shape[1])]
    if rolling.camber_track_rad is not None:
        own.append(rolling.camber_track_rad)
    own += list(rolling.camber_basis.values())
    a = np.column_stack(own)
    coef, *_ = np.linalg.lstsq(a, basis.T, rcond=None)
    rest = basis - (a @ coef).T
    _, sv, vt = np.linalg.svd(rest, full_matrices=False)
    keep = sv > BEYOND_RTOL * (sv[0] if sv.size else 0.0)
    # rows scaled like the splines (≈ 1 at their peak), for the fit's conditioning
    return vt[keep] * np.sqrt(basis.shape[1] / 4.0)


def lean_check(
    result: CalibrationResult, extension: Extension, extended: WideNormal, spacing_s: float
) -> LeanCheck:
    """The score and Hausman test of the free camber at ``result`` (module docstring).

    ``extended``: H, g and the sandwich's meat M of the extension's model at the fit,
    in the extension's order (:func:`~wheelcal.estimate.field.robust.robust_result_with`).
    Both tests take their variance from M, as the reported σ do (a road's noise follows
    the speed, which the stationary noise model cannot): the shift δ = A G and the
    score u = B G are linear in the score G, so Var = A M Aᵀ, B M Bᵀ.
    """
    base, added = extension.index, extension.added
    order = np.concatenate([base, added])
    h = extended.hess[np.ix_(order, order)]
    g = extended.grad[order]
    meat = extended.meat[np.ix_(order, order)]
    size = base.size
    h_bb_inv = scaled_pinv(h[:size, :size])
    h_inv = scaled_pinv(h)
    wide = order.size
    # the score test of the spline coefficients: u = g_e − H_eb H_bb⁻¹ g_b = B G
    b = np.zeros((wide - size, wide))
    b[:, :size] = -h[size:, :size] @ h_bb_inv
    b[:, size:] = np.eye(wide - size)
    u = b @ g
    var_u = b @ meat @ b.T
    statistic = float(u @ scaled_pinv(var_u) @ u)
    diag = np.sqrt(np.maximum(np.outer(np.diag(var_u), np.diag(var_u)), 1e-300))
    singular = np.linalg.svd(var_u / diag, compute_uv=False)
    dof = int(np.sum(singular > RANK_RTOL * singular[0]))
    p_value = float(special.chdtrc(max(dof, 1), statistic))
    # one Gauss–Newton step of the wider model, net of the fit's own (tiny) step: δ = A G
    a = -h_inv[:size]
    a[:, :size] += h_bb_inv
    shift = a @ g
    var_shift = np.diag(a @ meat @ a.T)
    var_fit = np.diag(h_bb_inv @ meat[:size, :size] @ h_bb_inv)
    names = list(result.layout.names)
    sigma, z = {}, {}
    for name in CHECKED:
        if name not in names:
            continue
        k = names.index(name)
        if not (np.isfinite(var_fit[k]) and var_fit[k] > 0):
            continue
        delta = abs(float(shift[k]))
        sigma[name] = delta / float(np.sqrt(var_fit[k]))
        z[name] = delta / float(np.sqrt(max(var_shift[k], 1e-300)))
    return LeanCheck(statistic, dof, p_value, sigma, z, spacing_s)
