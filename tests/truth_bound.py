"""The Cramér–Rao bound at the *truth* of a simulated session, for the fitted window.

Tests judge an estimate by how far it lies from the truth in units of this
bound — never in units of the fit's own σ, which a broken fit can inflate.
The truth's spin is re-expressed about the fitted window's centre; a driven
wheel's motion (no polynomial) is represented by the degree-4 polynomial of
ϑ(t) closest to it over the window, which changes the bound on the sensor's
parameters negligibly.  The noise is the simulator's own: its AR model, or —
with vibration on top — an AR model estimated from a long draw of the
simulated noise alone (never from the fit's residual).
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.joint.crlb import Bound, cramer_rao_bound
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.model import CalibrationParams, SpinParams
from wheelcal.model.parameters import AXES

SENSOR_NAMES = tuple(f"gain_{a}" for a in AXES) + tuple(f"offset_{a}_mps2" for a in AXES)


def _truth_spin(session, t_centred: np.ndarray, centre_s: float) -> SpinParams:
    scenario = session.scenario
    if scenario.motion is None:
        return session.truth.spin.shifted(centre_s - session.centre_s)
    kin = scenario.motion.kinematics(t_centred + centre_s - session.centre_s)
    coef = np.polynomial.polynomial.polyfit(t_centred, kin.theta_rad, 4)
    return SpinParams(theta0_rad=coef[0], omega_radps=coef[1:] * np.arange(1, 5))


def scenario_noise(scenario) -> NoiseModel:
    """The simulator's noise as a NoiseModel (vibration included, from a long draw)."""
    rate = scenario.rate_hz
    if scenario.vibration is None:
        return NoiseModel.from_ar(
            scenario.noise.ar_polynomial(rate), scenario.noise.innovation_std(rate)
        )
    rng = np.random.default_rng(12345)
    n = 200_000
    draw = scenario.noise.sample(n, rate, rng) + scenario.vibration.sample(n, rate, rng)
    return NoiseModel.estimate(draw, max_order=10)


def bound_at_truth(session, result) -> Bound:
    """CRLB at the truth over ``result``'s fitted samples, in ``result``'s layout."""
    t_centred = result.time_s - result.centre_s
    truth = session.truth
    params = CalibrationParams(
        spin=_truth_spin(session, t_centred, result.centre_s),
        bench=truth.bench,
        sensor=truth.sensor,
        gravity_mps2=truth.gravity_mps2,
        effects=truth.effects,
    )
    assert result.layout.spin_degree == params.spin.degree
    return cramer_rao_bound(params, t_centred, scenario_noise(session.scenario), result.layout)


def sigmas_off(session, result, names=SENSOR_NAMES) -> dict[str, float]:
    """|estimate − truth| / σ_CRLB(truth) for the named parameters that are not undetermined."""
    bound = bound_at_truth(session, result)
    truth = dict(zip(bound.names, bound.values, strict=True))
    out = {}
    for name in names:
        if name in result.undetermined:
            continue
        out[name] = abs(result.value_of(name) - truth[name]) / bound.std_of(name)
    return out
