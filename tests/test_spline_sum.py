"""The wheel-angle spline evaluated without its basis matrix, and the basis cache's size."""

import numpy as np
import pytest

from wheelcal.model import effects
from wheelcal.model.effects import SpinSpline, cubic_bspline_basis, cubic_bspline_sum


@pytest.mark.parametrize(("first", "count"), [(0, 23), (4, 6), (17, 6), (0, 1)])
def test_the_sums_equal_the_basis_products(first, count):
    rng = np.random.default_rng(first + count)
    t = np.sort(rng.uniform(-8.0, 40.0, 4000))  # beyond both ends of the basis too
    coef = rng.normal(size=count)
    bases = cubic_bspline_basis(t, -2.0, 1.7, count, first)
    sums = cubic_bspline_sum(coef, t, -2.0, 1.7, first)
    for got, basis in zip(sums, bases, strict=True):
        want = coef @ basis
        assert np.max(np.abs(got - want)) <= 1e-12 * max(1.0, np.max(np.abs(want)))
    # Outside every basis function's support the sums vanish.
    outside = (t < -2.0 + 1.7 * (first - 3)) | (t >= -2.0 + 1.7 * (first + count + 1))
    assert outside.any() and np.all(sums[0][outside] == 0.0)


def test_a_spline_without_jacobian_makes_no_basis():
    spline = SpinSpline(-45.0, 45.0, 0.5)
    t = np.linspace(-45.0, 45.0, 18001)
    values = np.random.default_rng(3).normal(size=spline.size)
    effects._BASIS_CACHE.clear()
    effects._BASIS_CACHE_BYTES[0] = 0
    fast = spline.spin_delta(values, t, None, jacobian=False)
    assert not effects._BASIS_CACHE
    full = spline.spin_delta(values, t, None, jacobian=True)
    assert np.allclose(fast.theta, full.theta, rtol=0, atol=1e-12)
    assert np.allclose(fast.omega_dot, full.omega_dot, rtol=0, atol=1e-9)


def test_the_cache_keeps_count_of_its_bytes():
    effects._BASIS_CACHE.clear()
    effects._BASIS_CACHE_BYTES[0] = 0
    spline = SpinSpline(0.0, 10.0, 1.0)
    for k in range(effects._BASIS_CACHE_SIZE + 20):
        spline.spin_delta(np.zeros(spline.size), np.linspace(0, 10, 50 + k), None, jacobian=True)
    held = sum(array.nbytes for hit in effects._BASIS_CACHE.values() for array in hit)
    assert len(effects._BASIS_CACHE) == effects._BASIS_CACHE_SIZE
    assert effects._BASIS_CACHE_BYTES[0] == held
