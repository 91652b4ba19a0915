"""Levenberg–Marquardt on the parameter manifold, with a statistical stopping rule.

The problem is min_x ‖r̃(x)‖² for a whitened residual r̃ (see
:mod:`wheelcal.estimate.noise_model`).  Steps are taken in the layout's flat
vector around the current point and mapped back with ``layout.unpack`` (which
moves R by exp([δ]×)), so the rotation never leaves SO(3).

Stopping: after a Gauss–Newton step the predicted decrease of the cost is
Δ = gᵀ(JᵀJ)⁻¹g.  With unit-variance whitened errors, Δ < ``tol`` means the step
is below √tol standard deviations of the parameters — further iterations would
only move the estimate by a negligible fraction of its own uncertainty.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from wheelcal.model import CalibrationParams, ParameterLayout

ResidualFn = Callable[[CalibrationParams, bool], tuple[np.ndarray, np.ndarray | None]]


@dataclass(frozen=True, eq=False)
class LMOutcome:
    """Where the iterations ended and why."""

    params: CalibrationParams
    residual: np.ndarray  # whitened, (3, M)
    jacobian: np.ndarray  # whitened, (P, 3, M)
    cost: float
    iterations: int
    converged: bool
    message: str


def levenberg_marquardt(
    residual_fn: ResidualFn,
    params0: CalibrationParams,
    layout: ParameterLayout,
    max_iterations: int = 50,
    tol: float = 1e-6,
    initial_damping: float = 1e-3,
) -> LMOutcome:
    """Minimise ‖residual_fn(params)‖² from ``params0``.

    ``residual_fn(params, want_jacobian)`` returns the whitened residual (3, M)
    and, when asked, its transposed Jacobian (P, 3, M) in ``layout`` order.
    ``initial_damping`` is λ relative to the scaled diagonal: small for a warm
    start (Gauss–Newton steps), larger far from the optimum.
    """
    params = params0
    r, j = residual_fn(params, True)
    cost = float(np.sum(r * r))
    lam = initial_damping
    message = "maximum iterations reached"
    converged = False
    iteration = 0
    for iteration in range(1, max_iterations + 1):
        jt = j.reshape(j.shape[0], -1)
        a = jt @ jt.T
        g = jt @ r.reshape(-1)
        scale = np.sqrt(np.maximum(np.diag(a), 1e-300))
        a_s = a / np.outer(scale, scale)
        g_s = g / scale
        gn_decrease = _gauss_newton_decrease(a_s, g_s)
        if gn_decrease < tol:
            converged, message = True, "step below tolerance (in units of the parameter σ)"
            iteration -= 1
            break
        accepted = False
        for _ in range(30):
            try:
                step_s = -np.linalg.solve(a_s + lam * np.eye(a_s.shape[0]), g_s)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            step = step_s / scale
            try:
                trial = layout.unpack(layout.pack(params) + step, params)
                r_trial, _ = residual_fn(trial, False)
                cost_trial = float(np.sum(r_trial * r_trial))
            except (ValueError, FloatingPointError):
                cost_trial = np.inf
            predicted = -(2 * step_s @ g_s + step_s @ a_s @ step_s)
            actual = cost - cost_trial
            if np.isfinite(cost_trial) and actual > 0:
                rho = actual / predicted if predicted > 0 else 0.0
                lam = lam * max(1 / 3, 1 - (2 * rho - 1) ** 3) if rho > 0 else lam * 2
                lam = max(lam, 1e-12)
                params, cost = trial, cost_trial
                accepted = True
                break
            lam *= 10.0
            if lam > 1e12:
                break
        if not accepted:
            converged = gn_decrease < 1e3 * tol
            message = "no further decrease possible" + ("" if converged else " (stalled)")
            break
        r, j = residual_fn(params, True)
        cost = float(np.sum(r * r))
    return LMOutcome(params, r, j, cost, iteration, converged, message)


def _gauss_newton_decrease(a_s: np.ndarray, g_s: np.ndarray) -> float:
    """gᵀA⁻¹g using a pseudo-inverse (A may be singular in unidentifiable directions)."""
    w, v = np.linalg.eigh(a_s)
    keep = w > w.max() * 1e-13
    proj = v[:, keep].T @ g_s
    return float(np.sum(proj**2 / w[keep]))
