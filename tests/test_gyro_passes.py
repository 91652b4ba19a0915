"""Stage 2 of the gyro-aided joint fit: two Jacobian passes over all samples.

As for the accelerometer alone (test_stage2_passes.py), stage 2 starts from
the canonical twin (the gyro's reading and the wheel-angle spline mirror with
it) and its last Gauss–Newton step, when below 0.3 σ, is confirmed by the cost
alone — also when the wheel angle's spline reproduces the cubic (a null
direction the step leaves alone).  Judged against the fully iterated fit (LM
from the result, same noise models, both streams): the calibration's values
within 0.05 σ and its σ within 1 %.
"""

import numpy as np
import pytest

from wheelcal.estimate.gyro.knots import choose_knot_spacing
from wheelcal.estimate.joint import fit as joint_module
from wheelcal.estimate.joint.fit import JointFit, _residual_fn, gyro_samples
from wheelcal.estimate.joint.gyro_equations import accumulate_gyro, combined
from wheelcal.estimate.joint.information import covariance_from_fisher
from wheelcal.estimate.joint.levenberg_marquardt import levenberg_marquardt
from wheelcal.estimate.joint.normal_equations import accumulate
from wheelcal.estimate.joint.reporting import report_transform, transform_covariance
from wheelcal.estimate.joint.systematic import nuisance_columns, nuisance_extra
from wheelcal.session.fit import SessionFit
from wheelcal.session.window import find_motion_window
from wheelcal.simulate import hostile
from wheelcal.simulate.gyro import GyroSpec

#: The wheel's motion (cubic and spline) is degenerate: its σ are not compared.
MOTION = ("theta0", "omega", "spin_spline.")


def _window_and_fitter(session):
    recording = session.recording
    found = find_motion_window(recording)
    window = recording.window(found.start_s, found.end_s)
    tc = window.time_s - 0.5 * (window.time_s[0] + window.time_s[-1])
    spacing = choose_knot_spacing(*gyro_samples(window, tc)).spacing_s
    return window, JointFit(use_gyro=True, spline_spacing_s=spacing)


def _sessions():
    yield "clean", hostile.clean(np.random.default_rng(1), gyro=GyroSpec())
    yield "pushes", hostile.three_pushes(np.random.default_rng(9), gyro=GyroSpec())


@pytest.fixture(scope="module", params=list(_sessions()), ids=lambda x: x[0])
def fitted(request):
    window, fitter = _window_and_fitter(request.param[1])
    return window, fitter, fitter.fit(window)


def _counting_full_passes(monkeypatch, samples: int) -> list[bool]:
    passes: list[bool] = []
    original = joint_module.accumulate_gyro

    def counting(params, t_s, *args, **kwargs):
        if t_s.size == samples:
            passes.append(args[3] if len(args) > 3 else kwargs.get("jacobian", True))
        return original(params, t_s, *args, **kwargs)

    monkeypatch.setattr(joint_module, "accumulate_gyro", counting)
    return passes


def test_gyro_aided_stage2_matches_the_fully_iterated_fit(fitted):
    window, _, result = fitted
    gyro_t, gyro = gyro_samples(window, result.centred_time_s)
    normal_fn = _residual_fn(
        result.centred_time_s,
        window.accel_mps2,
        result.layout,
        result.noise,
        gyro=(gyro_t, gyro, result.gyro_noise),
    )
    out = levenberg_marquardt(
        normal_fn, result.params, result.layout, 100, tol=1e-12, initial_damping=1e-9
    )
    _, values, g = report_transform(out.params, result.layout)
    std = np.sqrt(np.diag(transform_covariance(g, covariance_from_fisher(out.normal.hessian))))
    keep = [i for i, n in enumerate(result.names) if not n.startswith(MOTION)]
    assert len(keep) >= 20  # tilt, R, gains, offsets and the gyro's twelve
    assert result.converged
    z = (result.values[keep] - values[keep]) / std[keep]
    assert np.max(np.abs(z)) < 0.05, dict(zip(np.array(result.names)[keep], z, strict=True))
    assert np.allclose(result.std[keep] / std[keep], 1.0, rtol=0.01)


def test_gyro_aided_stage2_needs_two_jacobian_passes(monkeypatch):
    # Three pushes: 0.5 s knots (the spline reproduces the cubic: null directions),
    # and stage 2's second step is small enough to be confirmed by the cost alone.
    window, fitter = _window_and_fitter(
        hostile.three_pushes(np.random.default_rng(9), gyro=GyroSpec())
    )
    passes = _counting_full_passes(monkeypatch, gyro_samples(window, window.time_s)[0].size)
    result = fitter.fit(window)
    assert result.converged
    # Start and one Gauss–Newton step, then the last step's cost (before: three
    # Jacobian passes, and one more for the other twin when the fit ended there).
    assert passes == [True, True, False]


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_a_final_step_leaves_the_parameters_no_sample_sees_alone():
    # Seed 2: the disturbance trimming leaves out whole knot intervals, whose spline
    # coefficients no kept sample depends on; the refit's last step must not move them.
    session = hostile.three_pushes(np.random.default_rng(2), gyro=GyroSpec())
    out = SessionFit(gyro="on").run(session.recording)
    assert "left out" in out.window.reason
    assert np.all(np.isfinite(out.result.values))
    assert np.all(out.result.assessment.gyro.residual_rms_radps < 0.1)


def test_the_accelerometer_stream_without_the_gyro_rows_adds_up_the_same(fitted):
    window, _, result = fitted
    tc, layout = result.centred_time_s, result.layout
    gyro_t, gyro = gyro_samples(window, tc)
    nuisances = nuisance_columns(layout)
    assert nuisances  # extra columns after the free ones: they must stay last
    streams = (gyro_t, gyro, result.gyro_noise)
    got = _residual_fn(tc, window.accel_mps2, layout, result.noise, nuisances, gyro=streams)(
        result.params, True
    )
    # The accelerometer's stream over every row (the gyro's are zero there), plus the gyro's.
    acc = accumulate(
        result.params, tc, window.accel_mps2, layout, result.noise, extra=nuisance_extra(nuisances)
    )
    rate = accumulate_gyro(result.params, gyro_t, gyro, layout, result.gyro_noise)
    want = combined(acc, rate)
    scale = np.max(np.abs(want.hessian))
    assert np.max(np.abs(got.hessian - want.hessian)) <= 1e-12 * scale
    # g sums terms far larger than itself near the optimum: its rounding, in σ units.
    sigma = np.sqrt(np.diag(want.hessian))
    assert np.max(np.abs(got.gradient - want.gradient) / sigma) <= 1e-9
    assert got.cost == pytest.approx(want.cost, rel=1e-14) and got.entries == want.entries


def test_gyro_aided_stage1_takes_its_last_step_confirmed_by_the_cost(monkeypatch):
    session = hostile.clean(np.random.default_rng(1), gyro=GyroSpec())
    window, fitter = _window_and_fitter(session)
    full = gyro_samples(window, window.time_s)[0].size
    decimated: list[bool] = []
    original = joint_module.accumulate_gyro

    def counting(params, t_s, *args, **kwargs):
        if t_s.size < full:
            decimated.append(args[3] if len(args) > 3 else kwargs.get("jacobian", True))
        return original(params, t_s, *args, **kwargs)

    monkeypatch.setattr(joint_module, "accumulate_gyro", counting)
    assert fitter.fit(window).converged
    # Two Jacobian passes on the decimated copy (before: three), the last step's cost.
    assert decimated.count(True) == 2 and decimated[-1] is False


def test_the_gyro_stream_sums_do_not_depend_on_the_chunks(fitted):
    window, _, result = fitted
    gyro_t, gyro = gyro_samples(window, result.centred_time_s)
    args = (result.params, gyro_t, gyro, result.layout, result.gyro_noise)
    whole = accumulate_gyro(*args, chunk=gyro_t.size)  # one chunk, the dense layout
    chunked = accumulate_gyro(*args)
    assert chunked.entries == whole.entries
    assert chunked.cost == pytest.approx(whole.cost, rel=1e-12)
    scale = np.max(np.abs(whole.hessian))
    assert np.max(np.abs(chunked.hessian - whole.hessian)) <= 1e-12 * scale
    assert np.max(np.abs(chunked.gradient - whole.gradient)) <= 1e-9 * np.sqrt(scale)
