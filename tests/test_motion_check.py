"""The motion check's spline alternative: exact sums by parts, and its degrees of freedom.

check_motion accumulates the normal equations a few knot intervals at a time
with only the spline coefficients alive there; the sums must equal one dense
accumulation over every sample (FIR history carried across the parts).  Its
score test has as many degrees of freedom as the spline has directions
beyond the cubic's own: a cubic B-spline of ϑ spans 1, t, t², t³ — the
directions of ϑ₀, ω₀, ω₁, ω₂ — so dof = coefficients − 4.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from wheelcal.estimate.joint import JointFit
from wheelcal.estimate.motion_check import KNOT_SPACING_S, _normal_with_spline, check_motion
from wheelcal.estimate.normal_equations import accumulate
from wheelcal.model.effects import SpinSpline
from wheelcal.model.forward import candidate_columns
from wheelcal.simulate import NoiseSpec, simulate, table1


@pytest.fixture(scope="module", params=["white", "coloured"])
def fitted(request):
    scenario = table1()
    if request.param == "coloured":  # an AR noise model: the parts need FIR history
        scenario = dataclasses.replace(
            scenario, rate_hz=1000.0, noise=NoiseSpec(std_mps2=0.05, bandwidth_hz=40.0)
        )
    recording = simulate(scenario, np.random.default_rng(11)).recording
    return JointFit().fit(recording), recording


def test_sums_by_parts_equal_one_dense_accumulation(fitted):
    result, recording = fitted
    tc = result.centred_time_s
    spline = SpinSpline(float(tc[0]), float(tc[-1]), KNOT_SPACING_S)
    layout = result.layout

    def extra(params, output, t_s):
        return candidate_columns(params, t_s, layout, spline, output)

    dense = accumulate(result.params, tc, recording.accel_mps2, layout, result.noise, extra=extra)
    hess, grad = _normal_with_spline(result, recording.accel_mps2, result.noise, spline)
    scale = np.sqrt(np.outer(np.diag(dense.hessian), np.diag(dense.hessian)))
    np.testing.assert_allclose(hess / scale, dense.hessian / scale, rtol=0, atol=1e-10)
    np.testing.assert_allclose(
        grad / np.sqrt(np.diag(dense.hessian)),
        dense.gradient / np.sqrt(np.diag(dense.hessian)),
        rtol=0,
        atol=1e-9,
    )


def test_dof_are_the_spline_directions_beyond_the_cubic(fitted):
    result, recording = fitted
    check = check_motion(result, recording.accel_mps2, result.noise)
    tc = result.centred_time_s
    spline = SpinSpline(float(tc[0]), float(tc[-1]), check.spacing_s)
    assert check.dof == spline.size - 4
