"""J̃ᵀJ̃ by quadrature (estimate/joint/fisher_quadrature.py): exact on its rows, close to the sum.

Two separate claims:

* the rows: the weighted Gram of the kept whitened outputs, each from the model
  evaluated at its FIR cluster only, equals the same rows taken out of the
  whole whitened Jacobian (whitened by ``NoiseModel.whiten``, tested against
  scipy's lfilter in test_noise_model.py), to round-off, for white noise and
  AR colour of mixed per-axis orders;
* the rule: with the stride ``quadrature_stride`` picks, the σ from the
  quadrature's H are those of the full sum within 1e-4 of themselves (measured:
  2.2e-5 on Table I at 200 Hz with s = 11, 2.5e-5 at 1 kHz with s = 59, 5.9e-5 on
  the fast "rising" spin with s = 3) — and a stride far
  past the rule (2 rows per turn) misses by more, so the check can fail.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wheelcal.estimate.joint.fisher_quadrature import (
    MIN_ROWS_PER_TURN,
    quadrature_rows,
    quadrature_stride,
    stride_for,
)
from wheelcal.estimate.joint.fit import JointFit, residual_of
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.normal_equations import (
    _filled_buffer,
    accumulate,
    accumulate_fitting_noise,
    quadrature_hessian,
)
from wheelcal.estimate.joint.systematic import nuisance_columns, nuisance_extra
from wheelcal.session.fit import SessionFit
from wheelcal.simulate import NoiseSpec, hostile, simulate, table1


@pytest.mark.parametrize(("samples", "order", "stride"), [(1000, 0, 7), (1003, 2, 5), (50, 6, 9)])
def test_rows_cover_every_output_once(samples, order, stride):
    rows = quadrature_rows(samples, order, stride)
    outputs = samples - order
    assert rows.weights.sum() == outputs
    assert np.all(np.diff(rows.last) > 0)
    assert rows.last[0] >= order and rows.last[-1] == samples - 1
    # Each kept output is the centre of its cell of `stride` outputs (or a leftover).
    cells = outputs // stride
    centre = rows.last[:cells] - order
    np.testing.assert_array_equal(centre % stride, (stride - 1) // 2)
    np.testing.assert_array_equal(rows.samples[-1], rows.last)
    np.testing.assert_array_equal(rows.samples[0], rows.last - order)


def test_stride_is_odd_keeps_the_rows_per_turn_and_saves_evaluations():
    omega = 2 * np.pi * 1.4  # 143 samples per turn at 200 Hz
    s = quadrature_stride(200.0, omega, 0)
    assert s == 11 and 200.0 / (s * 1.4) >= MIN_ROWS_PER_TURN
    assert quadrature_stride(200.0, omega, 10) == 11  # clusters as long as the cells
    assert quadrature_stride(200.0, omega, 11) == 1  # longer: more evaluations than samples
    assert quadrature_stride(200.0, 2 * np.pi * 8.0, 0) == 1  # 25 samples per turn
    assert quadrature_stride(1000.0, omega, 3) == 59
    assert quadrature_stride(200.0, omega, 0, shortest_s=0.5) == 7  # 100 samples per knot
    assert quadrature_stride(200.0, 0.0, 0) == 1


@pytest.mark.parametrize(
    "omega_radps",
    [
        [8.0, -0.03, 1e-5, 0.0],  # a spin-down: fastest at the start
        [5.0, 0.0, 0.006, 0.0],  # fastest at both ends
        [13.75, 0.125, -0.003125, 0.0],  # rising and falling: 15 rad/s at t = 20 s, 13.75 at 0
        [2.0, 0.5, 0.0, -2e-4],  # |ω| largest at an end, a turning point inside
    ],
)
def test_stride_for_takes_the_fastest_turn_over_the_window(omega_radps):
    from wheelcal.model import SpinParams

    t = np.linspace(-45.0, 45.0, 18001)
    spin = SpinParams(theta0_rad=0.0, omega_radps=np.array(omega_radps))
    fastest = float(np.max(np.abs(spin.omega_at(t))))
    assert stride_for(t, spin, 0) == quadrature_stride(200.0, fastest, 0)


@pytest.fixture(scope="module")
def session():
    recording = simulate(table1(), np.random.default_rng(0)).recording
    outcome = SessionFit().run(recording)
    return outcome.result, outcome.window.recording


NOISES = {
    "white": NoiseModel.white([0.02, 0.03, 0.025]),
    "ar2-mixed": NoiseModel(
        (np.array([1.0, -0.9, 0.2]), np.array([1.0]), np.array([1.0, 0.5])),
        np.array([[4e-4, 1e-4, 0.0], [1e-4, 9e-4, 2e-4], [0.0, 2e-4, 6e-4]]),
    ),
    "ar5": NoiseModel.from_ar(np.array([1.0, -1.2, 0.5, -0.1, 0.05, 0.02]), 0.02),
}


@pytest.mark.parametrize("noise_name", list(NOISES))
def test_quadrature_rows_equal_the_same_rows_of_the_whole_whitened_jacobian(session, noise_name):
    result, window = session
    noise = NOISES[noise_name]
    layout, tc, v = result.layout, result.centred_time_s, window.accel_mps2
    extra = nuisance_extra(nuisance_columns(layout))
    rows = quadrature_rows(tc.size, noise.order, 7)
    got = quadrature_hessian(result.params, tc, layout, noise, rows, extra)
    buf, residual, _ = _filled_buffer(result.params, tc, v, layout, extra, extra.size)
    _, white = noise.whiten(residual, buf)
    kept = white[:-1, :, rows.last - noise.order] * np.sqrt(rows.weights)
    flat = kept.reshape(kept.shape[0], -1)
    expected = flat @ flat.T
    d = np.sqrt(np.diag(expected))
    np.testing.assert_allclose(got / np.outer(d, d), expected / np.outer(d, d), rtol=0, atol=1e-12)


def _sigma_error(result, window, noise, stride=None) -> float:
    """Largest relative difference of the fit's σ: quadrature H against the full sum."""
    layout, tc, v = result.layout, result.centred_time_s, window.accel_mps2
    if stride is None:
        stride = stride_for(tc, result.params.spin, noise.order)
    assert stride > 1
    rows = quadrature_rows(tc.size, noise.order, stride)
    quad = quadrature_hessian(result.params, tc, layout, noise, rows)
    full = accumulate(result.params, tc, v, layout, noise).hessian
    sigma_quad = np.sqrt(np.diag(np.linalg.inv(quad)))
    sigma_full = np.sqrt(np.diag(np.linalg.inv(full)))
    return float(np.max(np.abs(sigma_quad / sigma_full - 1)))


def _sessions():
    yield "table1", simulate(table1(), np.random.default_rng(0)).recording
    lowpass = table1(NoiseSpec(0.08, bandwidth_hz=20.0))
    yield "table1-lowpass", simulate(lowpass, np.random.default_rng(4)).recording
    fast = dataclasses.replace(table1(), rate_hz=1000.0, noise=NoiseSpec(0.05, bandwidth_hz=40.0))
    yield "1kHz-bandwidth40", simulate(fast, np.random.default_rng(11)).recording
    yield "rising", hostile.rising(np.random.default_rng(7)).recording


@pytest.mark.parametrize(("name", "recording"), list(_sessions()), ids=lambda x: str(x)[:16])
def test_the_rule_keeps_sigma_within_1e4_of_the_full_sum(name, recording):
    # The fit's noise model where the rule applies to it, and white noise (the largest
    # stride: AR(10) on "rising" needs clusters longer than its cells, so no quadrature).
    outcome = SessionFit().run(recording)
    result, window = outcome.result, outcome.window.recording
    white = NoiseModel.white(result.noise.marginal_std_mps2)
    assert _sigma_error(result, window, white) < 1e-4, name
    if name != "rising":
        assert _sigma_error(result, window, result.noise) < 1e-4, name


def test_a_stride_past_the_rule_misses(session):
    # 2 rows per turn (measured 8e-3; 3 per turn still gives 5e-4): the check above can fail.
    result, window = session
    assert _sigma_error(result, window, result.noise, stride=71) > 1e-3


def _one_chunk_session():
    return simulate(table1(), np.random.default_rng(0)).recording


def _several_chunks_session():
    # 1 kHz, 87 k samples: the residual, g and the clusters each a chunk at a time.
    scenario = dataclasses.replace(table1(), rate_hz=1000.0, noise=NoiseSpec(0.05, 40.0))
    return simulate(scenario, np.random.default_rng(11)).recording


@pytest.mark.parametrize("make", [_one_chunk_session, _several_chunks_session])
def test_stage2_start_takes_cost_and_gradient_over_every_sample(make):
    outcome = SessionFit().run(make())
    result, window = outcome.result, outcome.window.recording
    layout, tc, v = result.layout, result.centred_time_s, window.accel_mps2
    extra = nuisance_extra(nuisance_columns(layout))
    noise_of = JointFit()._noise_model
    normal, noise = accumulate_fitting_noise(result.params, tc, v, layout, noise_of, extra)
    size = layout.size
    assert normal.gradient.shape == (size,)  # gradient_pass's: the quadrature path was taken
    # The noise model of the residual at the start (evaluated a chunk at a time when long).
    expected_noise = noise_of(residual_of(result.params, tc, v, layout))
    np.testing.assert_array_equal(noise.innovation_cov, expected_noise.innovation_cov)
    expected = accumulate(result.params, tc, v, layout, noise, extra=extra)
    d = np.sqrt(np.diag(expected.hessian))
    assert normal.entries == expected.entries
    assert normal.cost == pytest.approx(expected.cost, rel=1e-12)
    np.testing.assert_allclose(
        normal.gradient / d[:size], expected.gradient[:size] / d[:size], rtol=0, atol=1e-9
    )
    # H by quadrature (nuisance columns included): close, not equal.
    scaled = (normal.hessian - expected.hessian) / np.outer(d, d)
    assert 0 < np.max(np.abs(scaled)) < 1e-4
