"""The motion check's spline alternative: exact sums, and its degrees of freedom.

check_motion accumulates the normal equations in one pass, the spline
coefficients' blocks a knot interval at a time with only the functions alive
there.  By parts over every sample (a fast spin, long AR filters, effects,
windows of several chunks), the sums must equal one dense accumulation (FIR
history carried across the intervals, even when it spans several).  By
quadrature (estimate/joint/fisher_quadrature.py), H must equal the same rows of the
dense whitened columns and g the dense gradient; the check's numbers then
stay within the quadrature's error of those computed from the dense sums.  Its
score test has as many degrees of freedom as the spline has directions
beyond the cubic's own: a cubic B-spline of ϑ spans 1, t, t², t³ — the
directions of ϑ₀, ω₀, ω₁, ω₂ — so dof = coefficients − 4.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

from wheelcal.estimate.joint import spline_normal, spline_quadrature
from wheelcal.estimate.joint.fisher_quadrature import quadrature_rows
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.estimate.joint.normal_equations import CHUNK_SAMPLES, _filled_buffer, accumulate
from wheelcal.estimate.joint.spline_normal import normal_with_spline
from wheelcal.model.effects import SpinSpline
from wheelcal.model.forward import candidate_columns
from wheelcal.session import motion_check
from wheelcal.session.motion_check import KNOT_SPACING_S, check_motion
from wheelcal.simulate import NoiseSpec, simulate, table1


@functools.cache
def _fitted(kind: str):
    scenario = table1()
    if kind == "coloured":  # an AR noise model: the parts need FIR history; 1 kHz: 3 chunks
        scenario = dataclasses.replace(
            scenario, rate_hz=1000.0, noise=NoiseSpec(std_mps2=0.05, bandwidth_hz=40.0)
        )
    recording = simulate(scenario, np.random.default_rng(11)).recording
    return JointFit().fit(recording), recording


@pytest.fixture(scope="module", params=["white", "coloured"])
def fitted(request):
    return _fitted(request.param)


@pytest.fixture
def by_parts(monkeypatch):
    """Every row: the quadrature's stride forced to 1."""
    monkeypatch.setattr(spline_normal, "stride_for", lambda *args: 1)


def test_sums_by_parts_equal_one_dense_accumulation(fitted, by_parts):
    result, recording = fitted
    tc = result.centred_time_s
    spline = SpinSpline(float(tc[0]), float(tc[-1]), KNOT_SPACING_S)
    layout = result.layout

    def extra(params, output, t_s):
        return candidate_columns(params, t_s, layout, spline, output)

    dense = accumulate(result.params, tc, recording.accel_mps2, layout, result.noise, extra=extra)
    hess, grad = normal_with_spline(result, recording.accel_mps2, result.noise, spline)
    scale = np.sqrt(np.outer(np.diag(dense.hessian), np.diag(dense.hessian)))
    np.testing.assert_allclose(hess / scale, dense.hessian / scale, rtol=0, atol=1e-10)
    np.testing.assert_allclose(
        grad / np.sqrt(np.diag(dense.hessian)),
        dense.gradient / np.sqrt(np.diag(dense.hessian)),
        rtol=0,
        atol=1e-9,
    )


@pytest.fixture(scope="module", params=["white", "lowpass"])
def one_chunk(request):
    """200 Hz, 90 s: one chunk, as the quadrature path takes it (AR(2) for the lowpass)."""
    noise = NoiseSpec(std_mps2=0.08, bandwidth_hz=20.0) if request.param == "lowpass" else None
    scenario = table1(noise) if noise else table1()
    recording = simulate(scenario, np.random.default_rng(5)).recording
    return JointFit().fit(recording), recording


def _quadrature_against_dense(result, recording, monkeypatch, stride):
    """H against the same rows of the dense whitened columns, g against the dense sums."""
    monkeypatch.setattr(spline_normal, "stride_for", lambda *args: stride)
    noise = result.noise
    tc = result.centred_time_s
    spline = SpinSpline(float(tc[0]), float(tc[-1]), KNOT_SPACING_S)
    layout = result.layout

    def extra(params, output, t_s):
        return candidate_columns(params, t_s, layout, spline, output)

    accel = recording.accel_mps2
    dense = accumulate(result.params, tc, accel, layout, noise, extra=extra)
    buf, residual, _ = _filled_buffer(result.params, tc, accel, layout, extra, None)
    _, white = noise.whiten(residual, buf)
    rows = quadrature_rows(tc.size, noise.order, stride)
    kept = white[:-1, :, rows.last - noise.order] * np.sqrt(rows.weights)
    flat = kept.reshape(kept.shape[0], -1)
    expected = flat @ flat.T
    hess, grad = normal_with_spline(result, accel, noise, spline)
    d = np.sqrt(np.diag(expected))
    np.testing.assert_allclose(hess / np.outer(d, d), expected / np.outer(d, d), atol=1e-10)
    d = np.sqrt(np.diag(dense.hessian))
    np.testing.assert_allclose(grad / d, dense.gradient / d, rtol=0, atol=1e-9)


@pytest.mark.parametrize("stride", [5, 9])
def test_sums_by_quadrature_equal_the_dense_rows_and_gradient(one_chunk, monkeypatch, stride):
    # The stride forced: the rule's own choice would be 7 here.
    result, recording = one_chunk
    assert result.noise.order < 4 and result.time_s.size <= CHUNK_SAMPLES
    _quadrature_against_dense(result, recording, monkeypatch, stride)


def test_sums_by_quadrature_over_several_chunks(monkeypatch):
    # 1 kHz: g a chunk at a time with FIR history, H's clusters in batches (forced small).
    result, recording = _fitted("coloured")
    assert result.time_s.size > CHUNK_SAMPLES and result.noise.order > 0
    monkeypatch.setattr(spline_quadrature, "CHUNK_SAMPLES", 3000)
    _quadrature_against_dense(result, recording, monkeypatch, 41)


def test_dof_are_the_spline_directions_beyond_the_cubic(fitted):
    result, recording = fitted
    check = check_motion(result, recording.accel_mps2, result.noise)
    tc = result.centred_time_s
    spline = SpinSpline(float(tc[0]), float(tc[-1]), check.spacing_s)
    assert check.dof == spline.size - 4


@pytest.mark.parametrize("samples_per_interval", [3, 12])
def test_sums_by_interval_when_the_fir_history_spans_several_intervals(
    fitted, samples_per_interval, by_parts
):
    # Knot intervals shorter than the AR order (white: one interval per slot block).
    result, recording = fitted
    part = slice(0, 1500)
    short = dataclasses.replace(result, time_s=result.time_s[part])
    tc = short.centred_time_s
    rate = (tc.size - 1) / (tc[-1] - tc[0])
    spline = SpinSpline(float(tc[0]), float(tc[-1]), samples_per_interval / rate)
    layout = short.layout
    accel = recording.accel_mps2[part]

    def extra(params, output, t_s):
        return candidate_columns(params, t_s, layout, spline, output)

    dense = accumulate(short.params, tc, accel, layout, short.noise, extra=extra)
    hess, grad = normal_with_spline(short, accel, short.noise, spline)
    d = np.sqrt(np.diag(dense.hessian))
    np.testing.assert_allclose(hess / np.outer(d, d), dense.hessian / np.outer(d, d), atol=1e-10)
    np.testing.assert_allclose(grad / d, dense.gradient / d, atol=1e-9)


def _dense_normal(result, accel_mps2, noise, spline, evaluated=None):
    """The sums by one accumulation with every coefficient as a dense extra column.

    ``evaluated`` (the fit's kept evaluation) is not used: the model is evaluated afresh.
    """

    def extra(params, output, t_s):
        return candidate_columns(params, t_s, result.layout, spline, output)

    dense = accumulate(
        result.params, result.centred_time_s, accel_mps2, result.layout, noise, extra=extra
    )
    return dense.hessian, dense.gradient


def _sessions():
    from wheelcal.simulate import hostile

    yield "table1", simulate(table1(), np.random.default_rng(3)).recording
    lowpass = dataclasses.replace(table1(), noise=NoiseSpec(std_mps2=0.08, bandwidth_hz=20.0))
    yield "table1-lowpass", simulate(lowpass, np.random.default_rng(4)).recording
    yield "rising", hostile.rising(np.random.default_rng(7)).recording
    yield "wandering", hostile.wandering(np.random.default_rng(300)).recording


@pytest.mark.parametrize(("name", "recording"), list(_sessions()), ids=lambda x: str(x)[:14])
def test_check_motion_equals_the_dense_computation(monkeypatch, name, recording):
    # As SessionFit runs it: the free-spin window, the broadband noise of its residual.
    # The Schur complement is near-singular (the spline spans the cubic's directions):
    # round-off moves the statistic by ~1e-6 of itself (measured: 2e-6 on table1, 5e-6
    # on the wandering motor).  H by quadrature moves it by ≤ 4e-4 of itself and a
    # shift by ≤ 4e-4 σ (measured at s = 11 on table1, the lowpass and three Table II sessions).
    from wheelcal.session import fit as sf

    choice = sf.choose_window(recording, max_window_s=sf.Gates().max_window_s)
    found = choice.found
    rests = sf.find_rests(recording, (found.start_s, found.end_s))
    result = JointFit().fit(choice.recording)
    fast, _ = sf._motion(result, choice.recording, rests)
    monkeypatch.setattr(motion_check, "normal_with_spline", _dense_normal)
    dense, _ = sf._motion(result, choice.recording, rests)
    assert fast.dof == dense.dof, name
    assert fast.statistic == pytest.approx(dense.statistic, rel=1e-3, abs=1e-4), name
    for key, shift in dense.shift_sigma.items():
        assert abs(fast.shift_sigma[key] - shift) < 1e-3, (name, key)
        # shift_z divides by √(σ²_flexible − σ²_cubic), a difference of near-equal
        # numbers: it is only compared where the shift is not negligible.
        if shift > 0.1:
            assert fast.shift_z[key] == pytest.approx(dense.shift_z[key], rel=1e-2), (name, key)
    if name == "wandering":  # the check has something to find here
        assert dense.inadequate(sf.Gates().motion_z, sf.Gates().motion_shift_sigma)
        assert fast.inadequate(sf.Gates().motion_z, sf.Gates().motion_shift_sigma)
