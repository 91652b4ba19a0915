"""The rests as a third stream of the effect screen: static readings the spin fit never saw.

A rest (:mod:`wheelcal.estimate.rests`) reads gravity alone, at an unknown wheel
angle ϑ_k: its mean m_k obeys eq. (6) with ω = ω̇ = 0,

    m_k = o + Γ R a(ϑ_k),   a(ϑ) = (g sinα cosϑ, g sinα sinϑ, g cosα),

with σ of the mean per axis (coloured noise included).  Added to the score tests
it pins what the spin alone trades: an imbalance's once-per-turn torque moves
the spin's gravity terms as the gains and the tilt do (its information fraction
falls to 0.2 % on a 20° bench), but it does not act at rest, so a fit that put
it into the gains predicts the rests wrong.  The rest angles ϑ_k are nuisance
parameters (their score is zero at their own best value, found here).

What acts at rest: the sensor (o, Γ, R), the tilt, and sensor effects; a spin
effect does not (its rows are zero).  A time-dependent sensor effect (a warm-up,
a drift) is taken at the fitted window's nearer end: the rests lie next to the
spin, and the effect's law is only known within the window (a warm-up's
exponential extrapolated a minute back would be a guess).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from wheelcal.estimate import RestSegment
from wheelcal.estimate.joint import CalibrationResult
from wheelcal.model import (
    CalibrationParams,
    Effect,
    ParameterLayout,
    SpinParams,
    candidate_columns,
    evaluate,
    spin_coefficient_names,
)


def usable_rests(fit: CalibrationResult, rests: tuple[RestSegment, ...]) -> tuple:
    """The rests the screen may use for this fit (none for a rolling wheel or a vertical one).

    A rolling wheel's rests are stops of a vehicle (a slope, a hand on the chassis);
    a vertical wheel has α fixed and its rests add nothing the screen needs.
    """
    if any(e.stage == "force" for e in fit.layout.effects):
        return ()
    if not fit.layout.fit_tilt:
        return ()
    return tuple(r for r in rests if np.all(np.isfinite(r.mean_mps2)) and r.samples >= 10)


def _at_rest(params: CalibrationParams, theta_rad: float) -> CalibrationParams:
    """The fit's parameters with the wheel standing at ϑ (ω and ω̇ zero)."""
    spin = SpinParams(theta0_rad=theta_rad, omega_radps=np.zeros(params.spin.omega_radps.size))
    effects = dict(params.effects)
    return params.with_changes(spin=spin, effects=effects)


def _static_layout(layout: ParameterLayout) -> ParameterLayout:
    """The layout without its spin effects (they do not act at rest)."""
    return dataclasses.replace(
        layout, effects=tuple(e for e in layout.effects if e.stage not in ("spin",))
    )


def _closed_form_angle(params: CalibrationParams, rest: RestSegment) -> float:
    """The rest's wheel angle from its mean seen in the bench frame: a = Rᵀ Γ⁻¹ (m − o)."""
    bench = params.static_force_mps2(rest.mean_mps2)
    return float(np.arctan2(bench[1], bench[0]))


def rest_normal(
    fit: CalibrationResult,
    rests: tuple[RestSegment, ...],
    candidates: tuple[Effect, ...],
    nuisance: ParameterLayout,
) -> tuple[np.ndarray, np.ndarray]:
    """H and g of the rests over [``nuisance``'s parameters | ϑ₁ … ϑ_R | the candidates].

    ``nuisance`` is the fit's layout, possibly with the gyro's reading after it
    (zero rows here).  Whitened by each rest mean's σ per axis; r = model − data.
    """
    layout = fit.layout
    static = _static_layout(layout)
    size, count = nuisance.size, len(rests)
    total = size + count + sum(c.size for c in candidates)
    hess, grad = np.zeros((total, total)), np.zeros(total)
    position = {name: i for i, name in enumerate(nuisance.names)}
    spin_rows = set(spin_coefficient_names(layout.spin_degree))
    tc = fit.centred_time_s
    for k, rest in enumerate(rests):
        t_s = float(np.clip(rest.mid_s - fit.centre_s, tc[0], tc[-1]))
        t = np.array([t_s])
        at_rest = _at_rest(fit.params, _closed_form_angle(fit.params, rest))
        out = evaluate(at_rest, t, static, jacobian=True)
        column = np.zeros((total, 3))
        for i, name in enumerate(static.names):
            if name == "theta0_rad":
                column[size + k] = out.jacobian[i, :, 0]
            elif name not in spin_rows:  # the spin law does not act at rest
                column[position[name]] = out.jacobian[i, :, 0]
        row = size + count
        for cand in candidates:
            if cand.stage == "sensor":
                column[row : row + cand.size] = _rest_columns(cand, at_rest, t, static, out)
            row += cand.size  # spin (and force) candidates do not act at rest
        weight = 1.0 / np.maximum(rest.mean_std_mps2, 1e-12)
        white = column * weight[None, :]
        residual = (out.predicted_mps2[0] - rest.mean_mps2) * weight
        # The angle at its best: one Gauss–Newton step from the closed form (which
        # weighs the axes alike), carried to the residual linearly.
        angle = white[size + k]
        residual -= angle * (float(angle @ residual) / max(float(angle @ angle), 1e-300))
        hess += white @ white.T
        grad += white @ residual
    return hess, grad


def _rest_columns(cand: Effect, params, t: np.ndarray, layout, out) -> np.ndarray:
    """∂v/∂θ (k, 3) of a sensor candidate at one rest reading."""
    lean = cand.axis_columns(t, out.sensed_mps2, params.sensor.gain)
    if lean is None:
        return candidate_columns(params, t, layout, cand, out)[:, :, 0]
    values, axes = lean
    column = np.zeros((cand.size, 3))
    column[np.arange(cand.size), list(axes)] = values[:, 0]
    return column
