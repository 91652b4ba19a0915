"""The Cramér–Rao bound at the truth for gyro-aided fits (accelerometer + gyro streams).

The gyro reading's truth is the simulator's: w = k_w·u from
:meth:`GyroSpec.wheel_axis_response` and the bias; the gyro noise is the
spec's white noise.  A driven wheel's true motion is represented in the
fitted layout (cubic + spline at the fitted knots) by the least-squares
projection of the true ϑ(t) — so the bound is the bound of the model fitted,
at the truth.
"""

from __future__ import annotations

import numpy as np

from truth_bound import scenario_noise
from wheelcal.estimate.joint.crlb import Bound, cramer_rao_bound_with_gyro
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.model import SpinParams
from wheelcal.model.effects import cubic_bspline_basis


def gyro_truth_values(spec, truth) -> np.ndarray:
    """The true (w, b, G_X, G_Y) of the gyro reading for a sensor mounted with R.

    The spec's sensitivity G acts on the sensed force R a: its columns along the
    bench's X and Y are G R e_X and G R e_Y, and G R e_Z times the constant
    g cosα belongs to the bias the reading shows on this bench.
    """
    rotation = truth.bench.misalignment.matrix
    k, u = spec.wheel_axis_response(rotation)
    g_sens = spec.g_sensitivity_radps_per_mps2
    g_cos = truth.gravity_mps2 * np.cos(truth.bench.tilt_rad)
    bias = np.asarray(spec.bias_radps) + g_sens @ rotation[:, 2] * g_cos
    return np.concatenate([k * u, bias, g_sens @ rotation[:, 0], g_sens @ rotation[:, 1]])


def gyro_bound(scenario, truth, true_theta, t_centred, layout) -> Bound:
    """CRLB of ``layout`` at the truth over ``t_centred``.

    ``true_theta`` is ϑ(t) of the true motion at ``t_centred``; ``truth`` gives
    the bench, the sensor and the effects other than the motion's.
    """
    spline = next((e for e in layout.effects if e.name == "spin_spline"), None)
    degree = layout.spin_degree
    poly = np.polynomial.polynomial.polyvander(t_centred, degree + 1)
    columns = [poly]
    if spline is not None:
        b, _, _ = cubic_bspline_basis(t_centred, spline.start_s, spline.spacing_s, spline.size)
        columns.append(b.T)
    design = np.hstack(columns)
    coef, *_ = np.linalg.lstsq(design, true_theta, rcond=None)
    phase = coef[: degree + 2]
    spin = SpinParams(theta0_rad=phase[0], omega_radps=phase[1:] * np.arange(1, degree + 2))
    effects = dict(truth.effects)
    if spline is not None:
        effects[spline.name] = coef[degree + 2 :]
    spec = scenario.gyro
    effects["gyro"] = gyro_truth_values(spec, truth)
    params = truth.with_changes(spin=spin, effects=effects)
    gyro_noise = NoiseModel.white(max(spec.noise_std_radps(scenario.rate_hz), 1e-9))
    return cramer_rao_bound_with_gyro(
        params, t_centred, scenario_noise(scenario), layout, gyro_noise
    )
