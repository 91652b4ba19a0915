"""The model at the fit's result, evaluated once by its last pass and kept for the motion check.

Each shortcut is compared with the straightforward computation: the Jacobian
formed from a kept evaluation with a fresh :func:`evaluate` (bit for bit), the
gradient pass given that evaluation with one that evaluates itself, and the
motion check given the fit's kept evaluation with one that evaluates again.
"""

import dataclasses

import numpy as np
import pytest

from wheelcal.estimate.joint.fit import JointFit
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.normal_equations import CHUNK_SAMPLES, accumulate, gradient_pass
from wheelcal.estimate.joint.systematic import nuisance_columns, nuisance_extra
from wheelcal.model import ParameterLayout, evaluate
from wheelcal.model.effects import QuadraticNonlinearity
from wheelcal.model.forward import EvaluatedModel
from wheelcal.session import fit as sf
from wheelcal.simulate import NoiseSpec, simulate, table1
from wheelcal.simulate.presets import random_setup


def _window(recording):
    choice = sf.choose_window(recording, max_window_s=sf.Gates().max_window_s)
    rests = sf.find_rests(recording, (choice.found.start_s, choice.found.end_s))
    return choice.recording, rests


@pytest.fixture(scope="module")
def fitted():
    recording = simulate(table1(), np.random.default_rng(8)).recording
    window, rests = _window(recording)
    result, evaluated = JointFit().fit_evaluated(window)
    return window, rests, result, evaluated


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("geometry", [{}, {"fit_tilt": False, "fit_radius": True}])
def test_a_jacobian_from_a_kept_evaluation_is_the_fresh_one(seed, geometry):
    rng = np.random.default_rng(seed)
    params = random_setup(rng).truth
    layout = ParameterLayout(**geometry)
    t = np.linspace(-20.0, 20.0, 3001)
    fresh = evaluate(params, t, layout, jacobian=True)
    kept = evaluate(params, t, layout)
    out = np.full((layout.size, 3, t.size), np.nan)
    shared = evaluate(params, t, layout, jacobian=True, out=out, output=kept)
    assert shared.jacobian is out
    np.testing.assert_array_equal(shared.jacobian, fresh.jacobian)
    np.testing.assert_array_equal(shared.predicted_mps2, fresh.predicted_mps2)
    for name in ("d_theta", "d_omega", "d_omega_dot", "theta_rad", "omega_radps"):
        np.testing.assert_array_equal(
            getattr(shared.kinematics, name), getattr(fresh.kinematics, name)
        )


def test_a_kept_evaluation_does_not_serve_effects_or_other_samples():
    params = random_setup(np.random.default_rng(4)).truth
    t = np.linspace(-5.0, 5.0, 101)
    kept = evaluate(params, t)
    effect = QuadraticNonlinearity(axis=0)
    with pytest.raises(ValueError):
        evaluate(params, t, ParameterLayout(effects=(effect,)), jacobian=True, output=kept)
    with pytest.raises(ValueError):
        evaluate(params, t[:50], ParameterLayout(), jacobian=True, output=kept)
    evaluated = EvaluatedModel(params, t, kept)
    assert evaluated.output_at(params, t.copy()) is kept
    assert evaluated.output_at(params, t + 1e-9) is None
    assert evaluated.output_at(params.with_changes(), t) is None


@pytest.mark.parametrize("coloured", [False, True])
def test_the_gradient_pass_from_a_kept_evaluation_is_the_same(fitted, coloured):
    window, _, result, _ = fitted
    tc, v, layout = result.centred_time_s, window.accel_mps2, result.layout
    noise = NoiseModel.estimate(result.residual_mps2) if coloured else result.noise
    a_res, b_res = np.empty_like(v), np.empty_like(v)
    a = gradient_pass(result.params, tc, v, layout, noise, residual_out=a_res)
    kept = evaluate(result.params, tc, layout)
    b = gradient_pass(result.params, tc, v, layout, noise, residual_out=b_res, output=kept)
    np.testing.assert_array_equal(a.gradient, b.gradient)
    np.testing.assert_array_equal(a_res, b_res)
    assert a.cost == b.cost


def test_the_fit_keeps_its_last_evaluation_at_the_result(fitted):
    window, _, result, evaluated = fitted
    assert evaluated is not None and evaluated.params is result.params
    fresh = evaluate(result.params, result.centred_time_s, result.layout)
    np.testing.assert_array_equal(evaluated.output.predicted_mps2, fresh.predicted_mps2)
    np.testing.assert_array_equal(result.residual_mps2, window.accel_mps2 - fresh.predicted_mps2)
    plain = JointFit().fit(window)
    np.testing.assert_array_equal(plain.values, result.values)
    np.testing.assert_array_equal(plain.covariance, result.covariance)


@pytest.mark.parametrize(("seed", "last"), [(0, "cost"), (2, "gradient")])
def test_either_last_pass_keeps_its_evaluation(monkeypatch, seed, last):
    # The LM's last pass is the cost-only one confirming a last step (seed 0) or a
    # gradient pass whose step ended below the tolerance (seed 2): both keep theirs.
    from wheelcal.estimate.joint import fit as joint_module

    passes: list[str] = []
    call, gradient = joint_module._LastResidual.__call__, joint_module._LastResidual.gradient

    def spy_call(self, params, want_jacobian):
        passes.append("jacobian" if want_jacobian else "cost")
        return call(self, params, want_jacobian)

    def spy_gradient(self, params):
        passes.append("gradient")
        return gradient(self, params)

    monkeypatch.setattr(joint_module._LastResidual, "__call__", spy_call)
    monkeypatch.setattr(joint_module._LastResidual, "gradient", spy_gradient)
    recording = simulate(table1(), np.random.default_rng(seed)).recording
    result, evaluated = JointFit().fit_evaluated(recording)
    assert passes[-1] == last
    assert evaluated is not None and evaluated.params is result.params
    fresh = evaluate(result.params, result.centred_time_s, result.layout)
    np.testing.assert_array_equal(evaluated.output.predicted_mps2, fresh.predicted_mps2)
    np.testing.assert_array_equal(evaluated.output.force.sin_theta, fresh.force.sin_theta)
    np.testing.assert_array_equal(result.residual_mps2, recording.accel_mps2 - fresh.predicted_mps2)


def test_the_motion_check_from_the_kept_evaluation_is_the_same(fitted):
    window, rests, result, evaluated = fitted
    shared, shared_reference = sf._motion(result, window, rests, evaluated)
    fresh, fresh_reference = sf._motion(result, window, rests)
    assert shared == fresh
    np.testing.assert_array_equal(shared_reference.broadband_mps2, fresh_reference.broadband_mps2)


def test_no_evaluation_is_kept_beyond_one_chunk_or_with_effects():
    recording = simulate(table1(NoiseSpec(0.05)), np.random.default_rng(9)).recording
    window, _ = _window(recording)
    _, evaluated = JointFit(effects=(QuadraticNonlinearity(axis=0),)).fit_evaluated(window)
    assert evaluated is None
    fast = dataclasses.replace(table1(), rate_hz=400.0)  # 36 k samples: two chunks
    window, _ = _window(simulate(fast, np.random.default_rng(10)).recording)
    assert window.time_s.size > CHUNK_SAMPLES
    result, evaluated = JointFit().fit_evaluated(window)
    assert evaluated is None and result.converged


@pytest.mark.parametrize("coloured", [False, True])
def test_the_hessian_from_a_gradient_pass_jacobian_is_the_same(fitted, coloured):
    # With effects a gradient pass forms J (no reverse mode); the LM's Hessian at the same
    # point takes it instead of evaluating the model again: the same sums, bit for bit.
    window, _, result, _ = fitted
    effect = QuadraticNonlinearity(axis=0)
    layout = dataclasses.replace(result.layout, effects=(effect,))
    params = result.params.with_changes(effects={effect.name: [1e-3]})
    tc, v = result.centred_time_s, window.accel_mps2
    noise = NoiseModel.estimate(result.residual_mps2) if coloured else result.noise
    formed: list = []
    gradient_pass(params, tc, v, layout, noise, evaluated_out=formed)
    assert len(formed) == 1 and formed[0].jacobian is not None
    extra = nuisance_extra(nuisance_columns(layout))
    fresh = accumulate(params, tc, v, layout, noise, extra=extra)
    shared = accumulate(params, tc, v, layout, noise, extra=extra, evaluated=formed)
    np.testing.assert_array_equal(shared.hessian, fresh.hessian)
    np.testing.assert_array_equal(shared.gradient, fresh.gradient)
    assert shared.cost == fresh.cost
    with pytest.raises(ValueError):
        accumulate(params, tc[:-1], v[:-1], layout, noise, evaluated=formed)


def test_each_chunk_takes_its_own_jacobian():
    effect = QuadraticNonlinearity(axis=0)
    layout = ParameterLayout(effects=(effect,))
    truth = random_setup(np.random.default_rng(4)).truth
    params = truth.with_changes(effects={effect.name: [1e-3]})
    t = np.linspace(-60.0, 60.0, CHUNK_SAMPLES + 10)
    v = evaluate(truth, t).predicted_mps2 + np.random.default_rng(5).normal(0, 0.05, (t.size, 3))
    noise = NoiseModel.from_ar(np.array([1.0, -0.5]), 0.05)
    formed: list = []
    gradient_pass(params, t, v, layout, noise, evaluated_out=formed)
    assert len(formed) == 2
    fresh = accumulate(params, t, v, layout, noise)
    shared = accumulate(params, t, v, layout, noise, evaluated=formed)
    np.testing.assert_array_equal(shared.hessian, fresh.hessian)
    np.testing.assert_array_equal(shared.gradient, fresh.gradient)
    with pytest.raises(ValueError):
        accumulate(params, t, v, layout, noise, evaluated=formed[:1])
