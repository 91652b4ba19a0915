"""The truth of a simulated session in a calibration's own terms, and the CRLB there.

A calibration reports its parameters in its final model (the closed loop's
layout: the paper's model plus the effects it found), over the samples it
fitted, about its own window centre.  The simulator's truth is re-expressed the
same way — never from the estimate's values:

* the spin: a polynomial truth shifted to the fitted centre; an imbalance's
  base motion (eq. 2) shifted, plus its (sin, cos) torque; any other motion (a
  drag spin-down, pushes) by the least-squares projection of the true ϑ(t) onto
  the layout's cubic, its extension and its spline;
* drifting effects (a warm-up, a drift) re-centred: their value at the fitted
  centre moves into the offset or the gain (the contract reports them there),
  their law keeps its shape;
* a gyro reading's truth from the simulator's gyro (``gyro_truth.py``).

The bound is then :func:`~wheelcal.estimate.joint.crlb.cramer_rao_bound` (with the
gyro's stream when the layout fits it) at that truth, with the simulator's noise.
"""

from __future__ import annotations

import numpy as np

from gyro_truth import gyro_truth_values
from truth_bound import scenario_noise, split_session
from wheelcal.estimate.joint.crlb import Bound, cramer_rao_bound, cramer_rao_bound_with_gyro
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.model import SpinParams
from wheelcal.model.effects import (
    GainDrift,
    OffsetDrift,
    OffsetWarmup,
    QuadraticNonlinearity,
    cubic_bspline_basis,
)
from wheelcal.model.parameters import SensorParams
from wheelcal.simulate.motion import ImbalancedSpin

SENSOR = ("gain_x", "gain_y", "gain_z", "offset_x_mps2", "offset_y_mps2", "offset_z_mps2")


def _spin(session, result, tc: np.ndarray, shift: float) -> tuple[SpinParams, dict]:
    """The true spin in the result's layout (cubic, extension, spline) and those effects."""
    motion = session.scenario.motion
    base = motion.base if isinstance(motion, ImbalancedSpin) else motion
    effects = {e.name: e for e in result.layout.effects}
    extension = effects.get("spin_extension")
    spline = effects.get("spin_spline")
    values = {}
    if isinstance(motion, ImbalancedSpin):
        values["imbalance"] = np.array([motion.sin_radps2, motion.cos_radps2])
    if base is None or isinstance(base, SpinParams):
        spin = (session.truth.spin if base is None else base).shifted(shift)
        if extension is not None:
            values["spin_extension"] = np.zeros(extension.size)
        if spline is not None:
            values["spin_spline"] = np.zeros(spline.size)
        return spin, values
    theta = base.kinematics(tc + shift).theta_rad
    degree = result.layout.spin_degree + (extension.extra_degrees if extension else 0)
    columns = [np.polynomial.polynomial.polyvander(tc, degree + 1)]
    if spline is not None:
        b, _, _ = cubic_bspline_basis(tc, spline.start_s, spline.spacing_s, spline.size)
        columns.append(b.T)
    coef, *_ = np.linalg.lstsq(np.hstack(columns), theta, rcond=None)
    omega = coef[1 : degree + 2] * np.arange(1, degree + 2)
    spin = SpinParams(theta0_rad=coef[0], omega_radps=omega[: result.layout.spin_degree + 1])
    if extension is not None:
        values["spin_extension"] = omega[result.layout.spin_degree + 1 :]
    if spline is not None:
        values["spin_spline"] = coef[degree + 2 :]
    return spin, values


def _sensor_effects(session, result, shift: float) -> tuple[SensorParams, dict]:
    """The sensor and its declared effects at the fitted centre, in the found parametrisation."""
    truth = session.truth
    offset = np.array(truth.sensor.offset_mps2, dtype=float)
    gain = np.array(truth.sensor.gain, dtype=float)
    found = {e.name: e for e in result.layout.effects}
    values = {}
    for effect in session.scenario.effects:
        true = np.asarray(truth.effects[effect.name], dtype=float)
        if isinstance(
            effect, OffsetWarmup
        ):  # a(1 − e^{−(t+Δ)/τ}) = a(1 − e^{−Δ/τ}) + a e^{−Δ/τ}(…)
            decay = np.exp(-shift / effect.tau_s)
            offset += true * (1 - decay)
            true = true * decay
        elif isinstance(effect, OffsetDrift):
            offset += true * shift
        elif isinstance(effect, GainDrift):
            scale = 1 + true * shift
            gain = gain * scale
            true = true / scale
        elif not isinstance(effect, QuadraticNonlinearity):
            raise ValueError(f"no re-centring for {effect!r}")
        if effect.name in found:
            values[effect.name] = found[effect.name].values_from(true, effect)
    return SensorParams(offset_mps2=offset, gain=gain), values


def truth_in(session, result):
    """The simulator's truth in ``result``'s layout, window centre and parametrisation."""
    tc = result.time_s - result.centre_s
    shift = result.centre_s - session.centre_s  # the truth's t = 0 is the true window centre
    spin, values = _spin(session, result, tc, shift)
    sensor, sensor_values = _sensor_effects(session, result, shift)
    values.update(sensor_values)
    for effect in result.layout.effects:  # found but absent in the truth: zero
        values.setdefault(effect.name, np.zeros(effect.size))
    if "gyro" in values:
        values["gyro"] = gyro_truth_values(session.scenario.gyro, session.truth)
    return session.truth.with_changes(spin=spin, sensor=sensor, effects=values)


def bound_in(session, result) -> Bound:
    """The CRLB at the truth for ``result``'s model over its fitted samples."""
    params = truth_in(session, result)
    tc = result.time_s - result.centre_s
    noise = scenario_noise(session.scenario)
    if any(e.stage == "gyro" for e in result.layout.effects):
        spec = session.scenario.gyro
        gyro_noise = NoiseModel.white(max(spec.noise_std_radps(session.scenario.rate_hz), 1e-9))
        return cramer_rao_bound_with_gyro(
            params, tc, noise, result.layout, gyro_noise, result.gyro_rests
        )
    return cramer_rao_bound(params, tc, noise, result.layout)


def sigmas_from_truth(session, fitted, names=SENSOR) -> dict[str, float]:
    """(estimate − truth) / σ_CRLB(truth) for the named parameters the result determined."""
    result, undetermined = split_session(fitted)
    bound = bound_in(session, result)
    truth = dict(zip(bound.names, bound.values, strict=True))
    return {
        n: (result.value_of(n) - truth[n]) / bound.std_of(n) for n in names if n not in undetermined
    }
