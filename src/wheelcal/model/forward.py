"""The observation model v(t) = o + Γ R a(t) (eq. 6) and its analytic Jacobian.

For a free-parameter layout (see :mod:`wheelcal.model.layout`) the Jacobian
∂v/∂x has shape (N, 3, P).  With W = Γ R and a(t) from eq. (1):

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
    """Predicted samples (N, 3) in m/s² and, if asked for, ∂v/∂x (N, 3, P)."""

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
    with ``jacobian=True`` it is required and ∂v/∂x is returned in its order.
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

    n = t.size
    jac = np.zeros((n, 3, layout.size))
    blocks = layout.blocks
    w_mat = gain[:, None] * rot  # W = Γ R

    def through_w(da: np.ndarray) -> np.ndarray:  # bench-frame (N,3[,P]) → dv
        return np.einsum("ij,nj...->ni...", w_mat, da)

    # Spin coefficients through ϑ, ω, ω̇ (only a_X and a_Y depend on them).
    r = params.bench.radius_m
    dax = (
        -force.g_sin_tilt * force.sin_theta[:, None] * kin.d_theta
        + 2 * r * kin.omega_radps[:, None] * kin.d_omega
    )
    day = force.g_sin_tilt * force.cos_theta[:, None] * kin.d_theta + r * kin.d_omega_dot
    da_spin = np.zeros((n, 3, dax.shape[1]))
    da_spin[:, 0, :] = dax
    da_spin[:, 1, :] = day
    jac[:, :, blocks["spin"]] = through_w(da_spin)
    if layout.fit_tilt:
        jac[:, :, blocks["tilt"]] = through_w(d_force_d_tilt(force))[:, :, None]
    if layout.fit_radius:
        jac[:, :, blocks["radius"]] = through_w(d_force_d_radius(kin))[:, :, None]
    # Rotation: ∂(R exp([δ]×) a)/∂δ_k = R (e_k × a).
    a = force.accel_mps2
    e_cross_a = np.zeros((n, 3, 3))  # [:, :, k] = e_k × a
    e_cross_a[:, 1, 0], e_cross_a[:, 2, 0] = -a[:, 2], a[:, 1]
    e_cross_a[:, 0, 1], e_cross_a[:, 2, 1] = a[:, 2], -a[:, 0]
    e_cross_a[:, 0, 2], e_cross_a[:, 1, 2] = -a[:, 1], a[:, 0]
    jac[:, :, blocks["rotation"]] = through_w(e_cross_a)
    g_idx = np.arange(blocks["gain"].start, blocks["gain"].stop)
    o_idx = np.arange(blocks["offset"].start, blocks["offset"].stop)
    jac[:, [0, 1, 2], g_idx] = sensed
    jac[:, [0, 1, 2], o_idx] = 1.0
    return ModelOutput(predicted, jac, kin, force, sensed)


def predict(
    params: CalibrationParams, t_s: np.ndarray, layout: ParameterLayout | None = None
) -> np.ndarray:
    """v(t) of eq. (6), shape (N, 3), in m/s²."""
    return evaluate(params, t_s, layout).predicted_mps2


def nuisance_sensitivity(params: CalibrationParams, t_s: np.ndarray, nuisance: str) -> np.ndarray:
    """∂v/∂q (N, 3) for a quantity the fit holds fixed: ``radius_m`` or ``gravity_mps2``.

    A sample-clock scale error ε is equivalent to a relative radius error of
    −2ε (ω and ω̇ are read in the wrong seconds while r ω² is not), so it needs
    no entry of its own.
    """
    out = evaluate(params, t_s)
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
