"""Levenberg–Marquardt on the parameter manifold, with a statistical stopping rule.

The problem is min_x ‖r̃(x)‖² for a whitened residual r̃ (see
:mod:`wheelcal.estimate.joint.noise_model`).  The iteration needs only the normal
equations H = J̃ᵀJ̃, g = J̃ᵀr̃ and the cost (accumulated in chunks by
:mod:`wheelcal.estimate.joint.normal_equations`).  Steps are taken in the layout's
flat vector around the current point and mapped back with ``layout.unpack``
(which moves R by exp([δ]×)), so the rotation never leaves SO(3).

Stopping: the predicted decrease of a Gauss–Newton step is Δ = gᵀH⁻¹g.  With
unit-variance whitened errors, Δ < ``tol`` means the step is below √tol
standard deviations of the parameters — further iterations would only move the
estimate by a negligible fraction of its own uncertainty.

A last step without a Jacobian (``final_step_tol``): when Δ is already small
(the step below √final_step_tol σ) but not below ``tol``, that Gauss–Newton
step is taken and only the cost is evaluated at its end (no Jacobian pass).
Gauss–Newton contracts the distance to the optimum by a factor c per step
(c ≈ 0.01 on a whitened spin), and the cost then falls by about (1 − c) Δ
instead of the predicted Δ.  The step is kept when the actual decrease is
within ``FINAL_STEP_RATIO`` of Δ (|c| ≤ 0.1): its end then lies within
0.1·√final_step_tol σ of the optimum (0.03 σ for final_step_tol = 0.1, the
stopping rule's own √tol), and the normal equations one short step back serve
as the Fisher information (they change by O(step / parameter scale)).  Else
the iterations go on as usual.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from wheelcal.estimate.joint.normal_equations import NormalEquations
from wheelcal.model import CalibrationParams, ParameterLayout

NormalFn = Callable[[CalibrationParams, bool], NormalEquations]


@dataclass(frozen=True, eq=False)
class LMOutcome:
    """Where the iterations ended and why.

    ``normal`` is evaluated at ``params`` — or, after a final step taken without
    a Jacobian (``final_step``), one step (< √final_step_tol σ) before it.  With
    a ``gradient_fn`` its Hessian may come from one step earlier still.
    """

    params: CalibrationParams
    normal: NormalEquations
    iterations: int
    converged: bool
    message: str
    final_step: bool = False
    #: ‖r̃‖² at ``params`` when ``normal`` is not evaluated there (a final step).
    end_cost: float | None = None

    @property
    def cost(self) -> float:
        """‖r̃‖² at ``params``."""
        return self.normal.cost if self.end_cost is None else self.end_cost


def levenberg_marquardt(
    normal_fn: NormalFn,
    params0: CalibrationParams,
    layout: ParameterLayout,
    max_iterations: int = 50,
    tol: float = 1e-6,
    initial_damping: float = 1e-3,
    jacobian_on_trial: bool = False,
    normal0: NormalEquations | None = None,
    final_step_tol: float | None = None,
    gradient_fn: Callable[[CalibrationParams], NormalEquations] | None = None,
) -> LMOutcome:
    """Minimise the whitened cost from ``params0``.

    ``normal_fn(params, want_jacobian)`` returns the :class:`NormalEquations`
    (cost only when ``want_jacobian`` is False).  ``initial_damping`` is λ
    relative to the scaled diagonal: small for a warm start (Gauss–Newton
    steps), larger far from the optimum.  ``jacobian_on_trial`` evaluates each
    trial point with its Jacobian: from a warm start nearly every step is
    accepted, and the accepted trial's normal equations are then the next
    iteration's (one pass over the samples per step instead of two).
    ``normal0`` is ``normal_fn(params0, True)`` when the caller has it already.
    ``final_step_tol`` (> ``tol``) allows a last step without a Jacobian (see
    the module doc).

    ``gradient_fn(params)`` (cost and gradient, no Hessian: cheaper than a
    Jacobian pass) evaluates the trials instead, and the Hessian of the point
    the step was taken from serves at the trial — for the stopping tests and the
    final step only: before any other step a Hessian of its own is evaluated.
    From a warm start one step lands within a small fraction of σ, where the
    Hessian of a point a few σ away differs by O(step / parameter scale).
    """
    params = params0
    normal = normal0 if normal0 is not None else normal_fn(params, True)
    fresh = True  # normal.hessian was evaluated at params
    lam = initial_damping
    message = "maximum iterations reached"
    converged = False
    iteration = 0
    size = layout.size  # the normal equations may carry extra columns after these
    evaluate = gradient_fn or (lambda trial: normal_fn(trial, jacobian_on_trial))  # at a trial
    for iteration in range(1, max_iterations + 1):
        scaled = _scaled(normal, size)
        if scaled.decrease < tol:
            converged, message = True, "step below tolerance (in units of the parameter σ)"
            iteration -= 1
            break
        if final_step_tol is not None and scaled.decrease < final_step_tol:
            last = _final_step(normal_fn, layout, params, scaled, normal.cost)
            if last is not None:
                return LMOutcome(
                    last[0],
                    normal,
                    iteration,
                    True,
                    f"last step ({np.sqrt(scaled.decrease):.2g} σ) confirmed by the cost",
                    final_step=True,
                    end_cost=last[1],
                )
        if not fresh:  # an earlier point's Hessian only serves the tests above
            normal, fresh = normal_fn(params, True), True
            scaled = _scaled(normal, size)
            if scaled.decrease < tol:
                converged, message = True, "step below tolerance (in units of the parameter σ)"
                break
        accepted = _damped_step(evaluate, layout, params, scaled, normal.cost, lam)
        if accepted is None:
            converged = scaled.decrease < 1e3 * tol
            message = "no further decrease possible" + ("" if converged else " (stalled)")
            break
        params, trial_normal, lam = accepted
        if gradient_fn is not None:
            normal = NormalEquations(
                trial_normal.cost, normal.hessian, trial_normal.gradient, trial_normal.entries
            )
            fresh = False
        else:
            normal = trial_normal if jacobian_on_trial else normal_fn(params, True)
    return LMOutcome(params, normal, iteration, converged, message)


def _damped_step(
    evaluate: Callable[[CalibrationParams], NormalEquations],
    layout: ParameterLayout,
    params: CalibrationParams,
    scaled: _ScaledNormal,
    cost: float,
    lam: float,
) -> tuple[CalibrationParams, NormalEquations, float] | None:
    """The damped step that lowers the cost: its end, ``evaluate`` there, and the next λ.

    λ (relative to the scaled diagonal) grows tenfold until a step lowers the
    cost; None when none does up to λ = 1e12.
    """
    a_s, g_s, scale, _ = scaled
    identity = np.eye(a_s.shape[0])
    while lam <= 1e12:
        try:
            step_s = -np.linalg.solve(a_s + lam * identity, g_s)
        except np.linalg.LinAlgError:
            lam *= 10.0
            continue
        step = step_s / scale
        try:
            trial = layout.unpack(layout.pack(params) + step, params)
            trial_normal = evaluate(trial)
            cost_trial = trial_normal.cost
        except (ValueError, FloatingPointError):
            cost_trial = np.inf
        predicted = -(2 * step_s @ g_s + step_s @ a_s @ step_s)
        actual = cost - cost_trial
        if np.isfinite(cost_trial) and actual > 0:
            rho = actual / predicted if predicted > 0 else 0.0
            lam = lam * max(1 / 3, 1 - (2 * rho - 1) ** 3) if rho > 0 else lam * 2
            return trial, trial_normal, max(lam, 1e-12)
        lam *= 10.0
    return None


#: The cost must fall by this fraction of the predicted decrease, at least and at most.
FINAL_STEP_RATIO = (0.9, 1.1)


def _final_step(
    normal_fn: NormalFn,
    layout: ParameterLayout,
    params: CalibrationParams,
    scaled: _ScaledNormal,
    cost: float,
) -> tuple[CalibrationParams, float] | None:
    """The Gauss–Newton step's end and its cost, when the cost confirms it; else None.

    One cost-only pass.
    """
    a_s, g_s, scale, _ = scaled
    if not np.all(np.diag(a_s) > 0):  # a parameter no sample depends on: iterate as usual
        return None
    w, v = np.linalg.eigh(a_s)
    keep = w > w.max() * UNDETERMINED_EIGEN_FRACTION
    exact = w <= w.max() * EXACT_NULL_EIGEN_FRACTION
    if np.any(~keep & ~exact):  # a direction the data barely determine: iterate as usual
        return None
    # Along an exact null direction (e.g. a wheel-angle spline that reproduces the
    # cubic) the cost is flat: no step there, as in the decrease the stopping rule measures.
    w, v = w[keep], v[:, keep]
    proj = v.T @ g_s
    predicted = float(np.sum(proj**2 / w))
    step_s = -(v @ (proj / w))
    try:
        trial = layout.unpack(layout.pack(params) + step_s / scale, params)
        end_cost = normal_fn(trial, False).cost
        actual = cost - end_cost
    except (ValueError, FloatingPointError):
        return None
    lo, hi = FINAL_STEP_RATIO
    if not (np.isfinite(actual) and lo * predicted <= actual <= hi * predicted):
        return None
    return trial, float(end_cost)


#: Scaled-Hessian eigenvalues at most this fraction of the largest are exact null directions
#: (rounding level: a spline that reproduces the cubic gives ~1e-16).
EXACT_NULL_EIGEN_FRACTION = 1e-12
#: Scaled-Hessian eigenvalues below this fraction of the largest mark directions the data
#: do not determine (σ along them > 10⁴ × the parameters' own scale).  Clean recordings
#: stay above 1e-5; an axis along the wheel axis or a radial axis gives 1e-10.
UNDETERMINED_EIGEN_FRACTION = 1e-8


class _ScaledNormal(NamedTuple):
    """H and g of the free parameters scaled to unit diagonal, the scale, and gᵀH⁻¹g."""

    a_s: np.ndarray
    g_s: np.ndarray
    scale: np.ndarray
    decrease: float


def _scaled(normal: NormalEquations, size: int) -> _ScaledNormal:
    """H and g of the free parameters scaled to unit diagonal, the scale, and gᵀH⁻¹g."""
    a, g = normal.hessian[:size, :size], normal.gradient[:size]
    scale = np.sqrt(np.maximum(np.diag(a), 1e-300))
    a_s = a / np.outer(scale, scale)
    g_s = g / scale
    return _ScaledNormal(a_s, g_s, scale, _gauss_newton_decrease(a_s, g_s))


def _gauss_newton_decrease(a_s: np.ndarray, g_s: np.ndarray) -> float:
    """gᵀA⁻¹g over the directions the data determine.

    A step along a direction the data do not determine (an exact or near null
    space, e.g. a rotation about a radial sensor axis traded against two gains)
    has no σ to be small against: such directions would keep the decrease
    above any tolerance while the cost stays flat, so they do not count.
    """
    w, v = np.linalg.eigh(a_s)
    keep = w > w.max() * UNDETERMINED_EIGEN_FRACTION
    proj = v[:, keep].T @ g_s
    return float(np.sum(proj**2 / w[keep]))
