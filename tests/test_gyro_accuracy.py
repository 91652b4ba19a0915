"""Gyro-aided calibration against the Cramér–Rao bound at the truth (issue 13).

* **The flexible angle costs nothing with a gyro**: on the paper's Table I (and
  Table II) free spin, the analytic CRLB of gains, offsets and tilt with the
  gyro and a spline wheel angle (knots 0.5–8 s) is ≤ 1.05× the accelerometer-only
  cubic CRLB; Monte Carlo spread / CRLB and reported σ / observed spread ≈ 1.
* **Imbalance**: with a 0.4 rad/s² once-per-turn torque, adding the imbalance
  effect to an accelerometer-only fit multiplies the CRLB by a setup-dependent
  factor (asserted in [1.3, 12]; ~1.6–5.6 on these setups); with the gyro the CRLB stays
  ≤ 1.3× the no-imbalance one; Monte Carlo consistent.
* **Driven motions** (a motor's ±10 % steps, three pushes, 0.5 m/s² vibration),
  through the whole session pipeline with ``--gyro on``: every determined gain and
  offset within 5 σ_CRLB at the truth, and reported σ / observed spread per group
  within the bounds below.

The Monte Carlo checks of free and imbalanced spins take σ_CRLB from
tests/independent_bound.py, not from wheelcal's CRLB code.  Statistics of the
Monte Carlo checks: with n runs the relative standard error of a standard
deviation is 1/√(2(n−1)); group ratios average 3 parameters.  CI (n = 12)
accepts spread/CRLB and reported/observed in [0.65, 1.4]; the slow versions
(n = 100) in [0.8, 1.25].
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

from gyro_truth import gyro_bound, gyro_truth_values
from independent_bound import independent_crlb
from wheelcal.estimate.joint.crlb import cramer_rao_bound, cramer_rao_bound_with_gyro
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.model import ParameterLayout
from wheelcal.model.effects import GyroReading, Imbalance, SpinSpline
from wheelcal.session.fit import SessionFit
from wheelcal.simulate import hostile, simulate, table1, table2
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.motion import ImbalancedSpin

GAINS = tuple(f"gain_{a}" for a in "xyz")
OFFSETS = tuple(f"offset_{a}_mps2" for a in "xyz")
SENSOR = GAINS + OFFSETS
SPEC = GyroSpec()


def _noise(scenario):
    rate = scenario.rate_hz
    return NoiseModel.from_ar(
        scenario.noise.ar_polynomial(rate), scenario.noise.innovation_std(rate)
    )


def _gyro_values(truth):
    return gyro_truth_values(SPEC, truth)


def _scenarios():
    return {"table1": table1(), "table2": table2(rng=np.random.default_rng(3))}


@pytest.mark.parametrize("name", ["table1", "table2"])
@pytest.mark.parametrize("spacing_s", [8.0, 2.0, 0.5])
def test_the_flexible_angle_costs_nothing_with_a_gyro(name, spacing_s):
    scenario = _scenarios()[name]
    t = scenario.centred_times_s()
    base = cramer_rao_bound(scenario.truth, t, _noise(scenario), ParameterLayout())
    spline = SpinSpline(t[0], t[-1], spacing_s)
    truth = scenario.truth.with_changes(
        effects={"gyro": _gyro_values(scenario.truth), spline.name: np.zeros(spline.size)}
    )
    layout = ParameterLayout(effects=(spline, GyroReading()))
    gyro_noise = NoiseModel.white(SPEC.noise_std_radps(scenario.rate_hz))
    flexible = cramer_rao_bound_with_gyro(truth, t, _noise(scenario), layout, gyro_noise)
    ratios = [flexible.std_of(n) / base.std_of(n) for n in (*SENSOR, "tilt_deg")]
    assert max(ratios) <= 1.05, ratios


def _imbalance_bounds(scenario, eps=0.4, phase=0.7):
    t = scenario.centred_times_s()
    noise = _noise(scenario)
    base = cramer_rao_bound(scenario.truth, t, noise, ParameterLayout())
    values = np.array([eps * np.cos(phase), eps * np.sin(phase)])
    with_imbalance = scenario.truth.with_changes(effects={"imbalance": values})
    acc = cramer_rao_bound(with_imbalance, t, noise, ParameterLayout(effects=(Imbalance(),)))
    truth = scenario.truth.with_changes(
        effects={"imbalance": values, "gyro": _gyro_values(scenario.truth)}
    )
    gyro_noise = NoiseModel.white(SPEC.noise_std_radps(scenario.rate_hz))
    layout = ParameterLayout(effects=(Imbalance(), GyroReading()))
    gyro = cramer_rao_bound_with_gyro(truth, t, noise, layout, gyro_noise)
    factor_acc = {n: acc.std_of(n) / base.std_of(n) for n in SENSOR}
    factor_gyro = {n: gyro.std_of(n) / base.std_of(n) for n in SENSOR}
    return factor_acc, factor_gyro, gyro


@pytest.mark.parametrize("name", ["table1", "table2"])
def test_imbalance_costs_the_accelerometer_alone_but_not_with_a_gyro(name):
    factor_acc, factor_gyro, _ = _imbalance_bounds(_scenarios()[name])
    assert 1.3 <= max(factor_acc.values()) <= 12.0, factor_acc
    assert min(factor_acc.values()) >= 1.0, factor_acc
    assert max(factor_gyro.values()) <= 1.3, factor_gyro


def _group_ratios(errors, crlb, reported):
    """Per group: observed spread / CRLB and reported σ / observed spread."""
    errors, crlb, reported = (np.asarray(x, dtype=float) for x in (errors, crlb, reported))
    observed = np.std(errors, axis=0, ddof=1)
    out = {}
    for group, index in (("gain", [0, 1, 2]), ("offset", [3, 4, 5])):
        out[group] = (
            float(np.mean(observed[index] / crlb[index])),
            float(np.mean(np.sqrt(np.mean(reported[:, index] ** 2, axis=0)) / observed[index])),
        )
    return out


def _monte_carlo_flexible(seeds, imbalance: bool):
    scenario = dataclasses.replace(table1(), gyro=SPEC)
    effects = ()
    if imbalance:
        eps, phase = 0.4, 0.7
        motion = ImbalancedSpin(scenario.truth.spin, eps * np.cos(phase), eps * np.sin(phase))
        scenario = dataclasses.replace(scenario, motion=motion)
        effects = (Imbalance(),)
    fitter = JointFit(effects=effects, use_gyro=True, spline_spacing_s=None if imbalance else 2.0)
    errors, reported = [], []
    for seed in seeds:
        result = fitter.fit(simulate(scenario, np.random.default_rng(seed)).recording)
        truth = dict(zip(result.names, result.values, strict=True))
        errors.append([truth[n] - _true(scenario, n) for n in SENSOR])
        reported.append([result.std_of(n) for n in SENSOR])
    bound = _independent_gyro_bound(imbalance)
    crlb = [bound.std_of(n) for n in SENSOR]
    return _group_ratios(errors, crlb, reported), np.abs(np.mean(errors, axis=0)) / crlb


@functools.cache
def _independent_gyro_bound(imbalance: bool):
    """The CRLB at the truth of the Monte Carlo below, independent of wheelcal's CRLB code.

    tests/independent_bound.py: finite differences of the accelerometer's and the
    gyro's predictions, numpy's inverse (test_independent_bound checks the analytic
    bound against it).
    """
    scenario = table1()
    t = scenario.centred_times_s()
    if imbalance:
        effect = Imbalance()
        values = np.array([0.4 * np.cos(0.7), 0.4 * np.sin(0.7)])
    else:
        effect = SpinSpline(t[0], t[-1], 2.0)
        values = np.zeros(effect.size)
    truth = scenario.truth.with_changes(
        effects={"gyro": _gyro_values(scenario.truth), effect.name: values}
    )
    return independent_crlb(
        truth,
        t,
        scenario.noise.std,
        free_effects=(effect, GyroReading()),
        gyro_std_radps=SPEC.noise_std_radps(scenario.rate_hz),
    )


def _true(scenario, name):
    sensor = scenario.truth.sensor
    axis = "xyz".index(name.split("_")[1])
    return sensor.gain[axis] if name.startswith("gain") else sensor.offset_mps2[axis]


@pytest.mark.parametrize("imbalance", [False, True])
def test_gyro_aided_fits_sit_on_their_bound_short(imbalance):
    ratios, bias = _monte_carlo_flexible(range(12), imbalance)
    for group, (spread, honest) in ratios.items():
        assert 0.65 <= spread <= 1.4, (group, spread)
        assert 0.65 <= honest <= 1.4, (group, honest)
    assert np.all(bias < 4.0 / np.sqrt(12) + 0.3), bias


@pytest.mark.slow
@pytest.mark.parametrize("imbalance", [False, True])
def test_gyro_aided_fits_sit_on_their_bound_full(imbalance):
    ratios, bias = _monte_carlo_flexible(range(100), imbalance)
    for group, (spread, honest) in ratios.items():
        assert 0.8 <= spread <= 1.25, (group, spread)
        assert 0.8 <= honest <= 1.25, (group, honest)
    # The imbalance effect is first order in ε/ω² (model/effects.py); at 0.4 rad/s² the
    # gyro is precise enough to see the second order, which leaves ≈ 0.5 σ_CRLB of bias
    # (measured 0.58 at most over 100 runs, standard error 0.1).
    assert np.all(bias < (0.75 if imbalance else 0.5)), bias


DRIVEN = {
    "motor steps": hostile.motor_steps,
    "three pushes": hostile.three_pushes,
    "vibration": lambda rng, gyro: hostile.vibrating(rng, 0.5, gyro=gyro),
}


def _driven_runs(builder, seeds):
    z, worst = [], []
    for seed in seeds:
        session = builder(np.random.default_rng(seed), gyro=SPEC)
        out = SessionFit(gyro="on").run(session.recording)
        result = out.result
        times = result.time_s
        theta = _true_theta(session, times)
        bound = gyro_bound(
            session.scenario, session.truth, theta, times - result.centre_s, result.layout
        )
        truth = {n: _true(session.scenario, n) for n in SENSOR}
        z.append([(result.value_of(n) - truth[n]) / result.std_of(n) for n in SENSOR])
        worst.append(max(abs(result.value_of(n) - truth[n]) / bound.std_of(n) for n in SENSOR))
    return np.array(z), np.array(worst)


def _true_theta(session, times):
    """ϑ(t) of the simulated motion at the recording times ``times``."""
    t = session.recording.time_s
    omega = session.omega_radps
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) * np.diff(t))])
    return np.interp(times, t, theta)


@pytest.mark.parametrize("name", sorted(DRIVEN))
def test_driven_motions_calibrate_within_5_sigma_crlb_short(name):
    z, worst = _driven_runs(DRIVEN[name], range(3))
    assert np.all(worst < 5.0), worst
    assert np.all(np.abs(z) < 5.0), z


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(DRIVEN))
def test_driven_motions_calibrate_within_5_sigma_crlb_full(name):
    z, worst = _driven_runs(DRIVEN[name], range(100))
    assert np.all(worst < 5.0), np.sort(worst)[-5:]
    for group, index in (("gain", [0, 1, 2]), ("offset", [3, 4, 5])):
        honest = float(np.mean(1.0 / np.std(z[:, index], axis=0, ddof=1)))
        assert 0.8 <= honest <= 1.25, (group, honest)


def test_auto_keeps_the_accelerometer_answer_and_calibrates_the_gyro_as_a_by_product(tmp_path):
    from wheelcal.calibration.session_json import calibration_dict
    from wheelcal.io import read_recording, write_recording

    session = hostile.clean(np.random.default_rng(21), gyro=SPEC)
    path = tmp_path / "spin.mcap"
    write_recording(session.recording, path)
    recording = read_recording(path)
    auto = SessionFit(gyro="auto").run(recording).result
    off = SessionFit(gyro="off").run(recording).result
    np.testing.assert_array_equal(auto.values, off.values)  # exactly the accelerometer's answer
    block = calibration_dict(auto)["gyro"]
    k, u = SPEC.wheel_axis_response(session.truth.bench.misalignment.matrix)
    assert abs(block["scale"] - k) < 5 * block["scale_std"] + 1e-4
    axis_error = np.abs(np.array(block["axis"]) - u)
    assert np.all(axis_error < 5 * np.array(block["axis_std"]) + 1e-3), axis_error
    # The bias is the reading at zero rate on this bench: the gyro's sensitivity to
    # the specific force adds to it, within the systematic σ the block states.
    error = np.abs(np.array(block["bias_radps"]) - SPEC.bias_radps)
    allowed = 5 * np.array(block["bias_std_radps"]) + 3 * np.array(
        block["bias_systematic_std_radps"]
    )
    assert np.all(error < allowed), (error, allowed)
    assert np.all(np.array(block["bias_systematic_std_radps"]) > 1e-3)  # ~0.3 °/s at ~3 g
    assert 0.3 < block["axis_angle_to_wheel_axis_deg"] < 3.0  # the spec's 1–2° misalignment
    assert "regression" in block["source"]
