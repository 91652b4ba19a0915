"""The observation model v(t) = o + Γ R a(t) (eq. 6) and its analytic Jacobian.

For a free-parameter layout (see :mod:`wheelcal.model.layout`) the Jacobian
is stored *transposed*, ``jacobian[p, i, n] = ∂v_i(t_n)/∂x_p`` with shape
(P, 3, N): every row is contiguous, which keeps filtering and JᵀJ fast.
With W = Γ R and a(t) from eq. (1):

* spin coefficient p:   W[:,0]·(−g sinα sinϑ ∂ϑ/∂p + 2rω ∂ω/∂p)
                       + W[:,1]·( g sinα cosϑ ∂ϑ/∂p + r ∂ω̇/∂p)
* tilt α:               W ∂a/∂α
* radius r:             W ∂a/∂r
* rotation δ_k:         Γ R (e_k × a)          (right perturbation R·exp([δ]×))
* gain γ_i:             e_i s_i,   s = R a
* offset o_i:           e_i
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model.bench import (
    BenchForce,
    bench_force,
    d_force_d_gravity,
    d_force_d_radius,
    d_force_d_tilt,
)
from wheelcal.model.kinematics import Kinematics, spin_kinematics
from wheelcal.model.layout import ParameterLayout
from wheelcal.model.parameters import CalibrationParams


@dataclass(frozen=True, eq=False)
class ModelOutput:
    """Predicted samples (N, 3) in m/s² and, if asked for, ∂v/∂x as (P, 3, N)."""

    predicted_mps2: np.ndarray
    jacobian: np.ndarray | None
    kinematics: Kinematics
    force: BenchForce
    sensed_mps2: np.ndarray


def evaluate(
    params: CalibrationParams,
    t_s: np.ndarray,
    layout: ParameterLayout | None = None,
    jacobian: bool = False,
) -> ModelOutput:
    """Evaluate eq. (6) at times ``t_s`` (s from the window centre).

    ``layout`` chooses the free parameters (and the effects in the model);
    with ``jacobian=True`` it is required and ∂v/∂x is returned in its order,
    shape (P, 3, N).
    """
    if jacobian and layout is None:
        raise ValueError("a Jacobian needs a ParameterLayout")
    t = np.asarray(t_s, dtype=float)
    kin = spin_kinematics(params.spin, t, derivatives=jacobian)
    force = bench_force(kin, params.bench.tilt_rad, params.bench.radius_m, params.gravity_mps2)
    rot = params.bench.misalignment.matrix
    gain = params.sensor.gain
    sensed = force.accel_mps2 @ rot.T  # Eq. (4): s = R a
    predicted = params.sensor.offset_mps2 + gain * sensed  # Eq. (5)
    if not jacobian:
        return ModelOutput(predicted, None, kin, force, sensed)

    jac = np.zeros((layout.size, 3, t.size))
    blocks = layout.blocks
    w_mat = gain[:, None] * rot  # W = Γ R
    # Spin coefficients act through ϑ, ω, ω̇ on a_X and a_Y only:
    # dv/dp = W[:,0]·∂a_X/∂p + W[:,1]·∂a_Y/∂p (outer products, no 3×3 per sample).
    r = params.bench.radius_m
    dax = -force.g_sin_tilt * force.sin_theta * kin.d_theta
    dax += (2 * r) * kin.omega_radps * kin.d_omega
    day = force.g_sin_tilt * force.cos_theta * kin.d_theta
    day += r * kin.d_omega_dot
    spin = blocks["spin"]
    for i in range(3):
        jac[spin, i, :] = w_mat[i, 0] * dax + w_mat[i, 1] * day
    if layout.fit_tilt:
        jac[blocks["tilt"].start] = (d_force_d_tilt(force) @ w_mat.T).T
    if layout.fit_radius:
        jac[blocks["radius"].start] = (d_force_d_radius(kin) @ w_mat.T).T
    # Rotation: ∂(R exp([δ]×) a)/∂δ_k = R (e_k × a), so dv/dδ_k = W (e_k × a):
    # e_x × a = (0, −a_Z, a_Y), e_y × a = (a_Z, 0, −a_X), e_z × a = (−a_Y, a_X, 0).
    a = force.accel_mps2
    rot0 = blocks["rotation"].start
    a_x, a_y, a_z = a[:, 0], a[:, 1], force.g_cos_tilt  # a_Z is a constant
    w_x, w_y, w_z = w_mat[:, 0, None], w_mat[:, 1, None], w_mat[:, 2, None]
    jac[rot0] = w_z * a_y - w_y * a_z
    jac[rot0 + 1] = w_x * a_z - w_z * a_x
    jac[rot0 + 2] = w_y * a_x - w_x * a_y
    for i in range(3):
        jac[blocks["gain"].start + i, i, :] = sensed[:, i]
        jac[blocks["offset"].start + i, i, :] = 1.0
    return ModelOutput(predicted, jac, kin, force, sensed)


def predict(
    params: CalibrationParams, t_s: np.ndarray, layout: ParameterLayout | None = None
) -> np.ndarray:
    """v(t) of eq. (6), shape (N, 3), in m/s²."""
    return evaluate(params, t_s, layout).predicted_mps2


def nuisance_sensitivity(
    params: CalibrationParams, t_s: np.ndarray, nuisance: str, output: ModelOutput | None = None
) -> np.ndarray:
    """∂v/∂q (N, 3) for a quantity the fit holds fixed: ``radius_m`` or ``gravity_mps2``.

    A sample-clock scale error ε is equivalent to a relative radius error of
    −2ε (ω and ω̇ are read in the wrong seconds while r ω² is not), so it needs
    no entry of its own.  ``output`` (an :func:`evaluate` result at the same
    parameters and times) saves evaluating the model again.
    """
    out = output if output is not None else evaluate(params, t_s)
    w_mat = params.sensor.gain[:, None] * params.bench.misalignment.matrix
    if nuisance == "radius_m":
        da = d_force_d_radius(out.kinematics)
    elif nuisance == "gravity_mps2":
        da = d_force_d_gravity(out.force, params.bench.tilt_rad)
    elif nuisance == "tilt_rad":
        da = d_force_d_tilt(out.force)
    else:
        raise ValueError(f"unknown nuisance quantity {nuisance!r}")
    return da @ w_mat.T
