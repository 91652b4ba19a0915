"""wheelcal's analytic Cramér–Rao bound against the independent one (tests/independent_bound.py).

The analytic bound (``wheelcal.estimate.joint.crlb``: analytic Jacobian, the noise
model's whitening, ``information.covariance_from_fisher``, the reporting
transform) must equal the bound rebuilt from finite differences of the
prediction, the exact AR likelihood and numpy's inverse.  Measured agreement:
1e-5 for white noise, ≤ 0.15 % for AR(2) noise (the analytic whitening drops
the first p samples' information), 1e-4 with the gyro stream and a spline
wheel angle, 2e-9 with the gyro and an imbalance; asserted within 1 %.  A σ scaled by 1.25
or 0.8 anywhere on the analytic path fails here at once.

Closed forms: an offset multiplies a constant regressor, so its Fisher
information is N/σ² for white noise and N·A(1)²/σ_e² (the long-run variance)
for AR noise, up to the first p samples; and freeing the other parameters can
only raise its bound above σ/√N (white).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from independent_bound import butterworth_ar, impulse_response, scenario_crlb
from wheelcal.model import ParameterLayout, SpinParams
from wheelcal.simulate import NoiseSpec, random_setup, table1
from wheelcal.study.montecarlo import scenario_bound

OFFSETS = tuple(f"offset_{a}_mps2" for a in "xyz")


def _reversed(scenario):
    spin = scenario.truth.spin
    truth = scenario.truth.with_changes(spin=SpinParams(-spin.theta0_rad, -spin.omega_radps))
    return dataclasses.replace(scenario, truth=truth)


def _scenarios():
    return {
        "table1-reversed-20Hz": _reversed(table1(NoiseSpec(0.08, bandwidth_hz=20.0))),
        "table1-white": table1(NoiseSpec(0.08)),
        "table1-20Hz": table1(NoiseSpec(0.08, bandwidth_hz=20.0)),
        "table1-0.2": table1(NoiseSpec(0.2)),
        "random-1": random_setup(np.random.default_rng(5), NoiseSpec((0.05, 0.08, 0.11))),
        "random-2": random_setup(np.random.default_rng(8), NoiseSpec(0.1, bandwidth_hz=30.0)),
        "random-3": random_setup(np.random.default_rng(21), NoiseSpec(0.06)),
    }


@pytest.mark.parametrize("name", list(_scenarios()))
def test_analytic_crlb_equals_the_independent_one(name):
    scenario = _scenarios()[name]
    independent = scenario_crlb(scenario)
    analytic = scenario_bound(scenario)
    assert analytic.names == independent.names
    np.testing.assert_allclose(analytic.values, independent.values, rtol=0, atol=1e-9)
    ratio = analytic.std / independent.std
    assert np.all(np.abs(ratio - 1) < 0.01), dict(zip(analytic.names, ratio.round(4), strict=True))
    # The correlations too (they enter every pooled statistic of the accuracy tests).
    corr = analytic.covariance / np.outer(analytic.std, analytic.std)
    corr_ind = independent.covariance / np.outer(independent.std, independent.std)
    assert np.max(np.abs(corr - corr_ind)) < 0.01


def test_both_spin_directions_are_covered():
    signs = {np.sign(s.truth.spin.omega_radps[0]) for s in _scenarios().values()}
    assert signs == {-1.0, 1.0}


@pytest.mark.parametrize("name", ["table1-white", "table1-20Hz", "random-1", "random-2"])
def test_offset_information_is_the_closed_form(name):
    scenario = _scenarios()[name]
    n = scenario.times_s().size
    std = scenario.noise.std
    a = butterworth_ar(scenario.noise.bandwidth_hz, scenario.rate_hz)
    if a is None:
        expected = n / std**2
    else:  # innovations e = A(z) x: a constant c becomes A(1)·c, of variance σ_e²
        sigma_e = std / np.sqrt(np.sum(impulse_response(a) ** 2))
        expected = n * np.sum(a) ** 2 / sigma_e**2
    independent = scenario_crlb(scenario)
    layout = ParameterLayout()
    analytic = scenario_bound(scenario, layout)
    for axis, name_o in enumerate(OFFSETS):
        i = independent.names.index(name_o)
        j = layout.index(name_o)
        tolerance = 1e-9 if a is None else 5.0 / n  # the first p samples
        assert abs(independent.fisher[i, i] / expected[axis] - 1) < tolerance
        assert abs(analytic.fisher[j, j] / expected[axis] - 1) < tolerance
        if a is None:
            # Other free parameters can only add to the bound of a constant term.
            assert independent.std_of(name_o) >= std[axis] / np.sqrt(n)
            assert analytic.std_of(name_o) >= std[axis] / np.sqrt(n)


def _gyro_case(name: str, kind: str):
    from gyro_truth import gyro_truth_values
    from wheelcal.estimate.joint.noise_model import NoiseModel
    from wheelcal.model.effects import GyroReading, Imbalance, SpinSpline
    from wheelcal.simulate import GyroSpec, table2

    spec = GyroSpec()
    scenario = table1() if name == "table1" else table2(rng=np.random.default_rng(3))
    t = scenario.centred_times_s()
    if kind == "spline":
        effect = SpinSpline(t[0], t[-1], 2.0)
        values = np.zeros(effect.size)
    else:
        effect, values = Imbalance(), np.array([0.4 * np.cos(0.7), 0.4 * np.sin(0.7)])
    truth = scenario.truth.with_changes(
        effects={"gyro": gyro_truth_values(spec, scenario.truth), effect.name: values}
    )
    noise = NoiseModel.white(scenario.noise.std)
    gyro_std = spec.noise_std_radps(scenario.rate_hz)
    return scenario, truth, (effect, GyroReading()), noise, gyro_std


@pytest.mark.parametrize(
    ("name", "kind"), [("table1", "imbalance"), ("table2", "imbalance"), ("table1", "spline")]
)
def test_analytic_crlb_with_gyro_equals_the_independent_one(name, kind):
    """Accelerometer + gyro streams, with an imbalance or a spline wheel angle fitted.

    With a spline the polynomial's ϑ₀, ω₀–ω₂ are redundant with it (∞ in the
    analytic bound); every other parameter must agree.
    """
    from independent_bound import independent_crlb
    from wheelcal.estimate.joint.crlb import cramer_rao_bound_with_gyro
    from wheelcal.estimate.joint.noise_model import NoiseModel

    scenario, truth, effects, noise, gyro_std = _gyro_case(name, kind)
    t = scenario.centred_times_s()
    layout = ParameterLayout(effects=effects)
    analytic = cramer_rao_bound_with_gyro(truth, t, noise, layout, NoiseModel.white(gyro_std))
    independent = independent_crlb(
        truth, t, scenario.noise.std, free_effects=effects, gyro_std_radps=gyro_std
    )
    assert set(analytic.names) == set(independent.names)
    finite = [n for n in analytic.names if np.isfinite(analytic.std_of(n))]
    assert len(finite) >= (23 if kind == "spline" else len(analytic.names))
    ratio = {n: analytic.std_of(n) / independent.std_of(n) for n in finite}
    assert all(abs(r - 1) < 0.01 for r in ratio.values()), ratio


@pytest.mark.parametrize("bandwidth_hz", [None, 20.0])
def test_analytic_crlb_with_sensor_and_spin_effects_equals_the_independent_one(bandwidth_hz):
    """Free effects of the closed loop (warm-up, nonlinearity, gain drift, imbalance)."""
    from independent_bound import independent_crlb
    from wheelcal.estimate.joint.crlb import cramer_rao_bound
    from wheelcal.estimate.joint.noise_model import NoiseModel
    from wheelcal.model.effects import GainDrift, Imbalance, OffsetWarmup, QuadraticNonlinearity

    scenario = _reversed(table1(NoiseSpec(0.08, bandwidth_hz=bandwidth_hz)))
    effects = (OffsetWarmup(25.0), QuadraticNonlinearity(0), GainDrift(), Imbalance())
    values = {
        "offset_warmup": [0.05, -0.02, 0.03],
        "nonlinearity_x": [1e-3],
        "gain_drift": [1e-5, -2e-5, 0.0],
        "imbalance": [0.05, -0.03],
    }
    truth = scenario.truth.with_changes(effects=values)
    t = scenario.centred_times_s()
    rate = scenario.rate_hz
    noise = NoiseModel.from_ar(
        scenario.noise.ar_polynomial(rate), scenario.noise.innovation_std(rate)
    )
    analytic = cramer_rao_bound(truth, t, noise, ParameterLayout(effects=effects))
    independent = independent_crlb(
        truth,
        t,
        scenario.noise.std,
        butterworth_ar(bandwidth_hz, rate),
        free_effects=effects,
    )
    assert analytic.names == independent.names
    ratio = analytic.std / independent.std
    assert np.all(np.abs(ratio - 1) < 0.01), dict(zip(analytic.names, ratio.round(4), strict=True))
