"""The knot spacing's criterion: the banded spline fit against a dense least squares."""

import numpy as np
import pytest

from wheelcal.estimate.gyro.knots import _spline_rss, choose_knot_spacing
from wheelcal.model.effects import cubic_bspline_basis


@pytest.mark.parametrize("intervals", [1, 5, 40])
def test_the_banded_fit_is_the_least_squares_fit(intervals):
    rng = np.random.default_rng(intervals)
    t = np.sort(rng.uniform(0.0, 30.0, 3000))
    s = np.sin(0.7 * t) + 0.3 * t + rng.normal(0.0, 0.05, t.size)
    step = (t[-1] - t[0]) / intervals
    basis, _, _ = cubic_bspline_basis(t, float(t[0]), step, intervals + 3)
    coef, *_ = np.linalg.lstsq(basis.T, s, rcond=None)
    dense = float(np.sum((s - coef @ basis) ** 2))
    assert _spline_rss(t, s, float(t[0]), step, intervals + 3) == pytest.approx(dense, rel=1e-9)


def test_a_step_in_the_rate_asks_for_fine_knots_and_a_smooth_rate_for_coarse():
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 90.0, 0.005)
    smooth = 10.0 - 0.02 * t
    stepped = smooth + 2.0 * (t > 40.0) * (1 - np.exp(-(t - 40.0).clip(0) / 0.3))
    axis = np.array([0.1, -0.2, 0.97])
    for rate, expect in ((smooth, 16.0), (stepped, 0.5)):
        gyro = np.outer(rate, axis) + rng.normal(0.0, 0.01, (t.size, 3))
        assert choose_knot_spacing(t, gyro).spacing_s == expect
