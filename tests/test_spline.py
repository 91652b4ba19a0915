"""The wheel-angle spline: its basis, its Jacobian, and the chunked normal equations.

* the four-values-per-sample basis equals the cardinal cubic B-spline formula
  (written out independently here), sums to 1, and its derivatives are the
  finite differences of it;
* the Jacobian of a model with a spline (and the gyro stream) equals finite
  differences of the prediction;
* the normal equations accumulated chunk by chunk through local views (only
  the basis functions alive in each chunk) equal the dense accumulation.
"""

import dataclasses

import numpy as np
import pytest

from wheelcal.estimate.joint.gyro_equations import accumulate_gyro
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.normal_equations import accumulate
from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    ParameterLayout,
    Rotation,
    SensorParams,
    SpinParams,
    evaluate,
    predict,
)
from wheelcal.model.effects import GyroReading, SpinSpline, cubic_bspline_basis


def _cardinal(t, start, spacing, count, first=0):
    u = (t[None, :] - start) / spacing - (first + np.arange(count))[:, None] + 3
    pieces = [
        ((u >= 0) & (u < 1), u**3 / 6),
        ((u >= 1) & (u < 2), (-3 * u**3 + 12 * u**2 - 12 * u + 4) / 6),
        ((u >= 2) & (u < 3), (3 * u**3 - 24 * u**2 + 60 * u - 44) / 6),
        ((u >= 3) & (u < 4), (4 - u) ** 3 / 6),
    ]
    return sum(np.where(m, v, 0.0) for m, v in pieces)


@pytest.mark.parametrize("first, count", [(0, 9), (3, 4)])
def test_basis_matches_the_cardinal_b_spline_and_its_derivatives(first, count):
    t = np.linspace(-15.0, 15.0, 6001)
    b, d1, d2 = cubic_bspline_basis(t, -15.0, 5.0, count, first)
    np.testing.assert_allclose(b, _cardinal(t, -15.0, 5.0, count, first), atol=1e-13)
    inner = slice(10, -10)
    np.testing.assert_allclose(np.gradient(b, t, axis=1)[:, inner], d1[:, inner], atol=2e-6)
    np.testing.assert_allclose(np.gradient(d1, t, axis=1)[:, inner], d2[:, inner], atol=2e-3)
    if first == 0:
        np.testing.assert_allclose(b.sum(axis=0), 1.0, atol=1e-12)


def _setup(spacing=2.0):
    spline = SpinSpline(-20.0, 20.0, spacing)
    rng = np.random.default_rng(5)
    params = CalibrationParams(
        spin=SpinParams(theta0_rad=0.3, omega_radps=(9.0, -0.05, 1e-4, 1e-6)),
        bench=BenchParams(np.deg2rad(40), 0.28, Rotation.from_euler_deg(10, 20, 30)),
        sensor=SensorParams(offset_mps2=(0.1, -0.1, 0.2), gain=(1.01, 0.99, 1.02)),
        effects={
            spline.name: rng.normal(0, 0.02, spline.size),
            "gyro": np.array(
                [-0.3, 0.4, -0.86, 0.01, -0.02, 0.005, 2e-4, -1e-4, 5e-5, 1e-4, 2e-4, -3e-5]
            ),
        },
    )
    layout = ParameterLayout(effects=(spline, GyroReading()))
    return params, layout


def test_jacobian_with_a_spline_equals_finite_differences():
    params, layout = _setup()
    t = np.linspace(-20, 20, 801)
    jac = evaluate(params, t, layout, jacobian=True).jacobian
    x0 = layout.pack(params)
    for k in range(layout.size):
        if layout.names[k].startswith("gyro."):
            continue  # the gyro does not act on the accelerometer
        h = 1e-5 / max(1.0, float(np.abs(jac[k]).max()))  # moves v by ~1e-5 m/s²
        up, down = x0.copy(), x0.copy()
        up[k] += h
        down[k] -= h
        fd = (
            predict(layout.unpack(up, params), t, layout)
            - predict(layout.unpack(down, params), t, layout)
        ) / (2 * h)
        np.testing.assert_allclose(jac[k].T, fd, atol=2e-5 * max(1.0, np.abs(fd).max()))


@pytest.mark.parametrize("ar", [np.array([1.0]), np.array([1.0, -0.6, 0.1])])
def test_chunked_local_views_equal_the_dense_normal_equations(ar):
    params, layout = _setup(spacing=1.0)  # 43 basis functions: the sparse path
    t = np.linspace(-20, 20, 8001)
    rng = np.random.default_rng(2)
    v = predict(params, t, layout) + rng.normal(0, 0.08, (t.size, 3))
    noise = NoiseModel.from_ar(ar, 0.05)
    sparse = accumulate(params, t, v, layout, noise)
    dense = accumulate(params, t, v, layout, noise, chunk=t.size + 1)
    scale = np.abs(dense.hessian).max()
    np.testing.assert_allclose(sparse.hessian, dense.hessian, rtol=1e-9, atol=1e-12 * scale)
    np.testing.assert_allclose(sparse.gradient, dense.gradient, rtol=1e-9, atol=1e-9)
    gyro = rng.normal(0, 0.002, (t.size, 3))
    g_sparse = accumulate_gyro(params, t, gyro, layout, noise)
    g_dense = accumulate_gyro(params, t, gyro, layout, noise, chunk=t.size + 1)
    g_scale = np.abs(g_dense.hessian).max()
    np.testing.assert_allclose(g_sparse.hessian, g_dense.hessian, rtol=1e-9, atol=1e-12 * g_scale)
    np.testing.assert_allclose(g_sparse.gradient, g_dense.gradient, rtol=1e-9, atol=1e-9)
    assert dataclasses.astuple(sparse)[0] == pytest.approx(dense.cost)


def test_gyro_stream_jacobian_equals_finite_differences():
    # H = JᵀJ of the gyro stream (unit white noise) against J from finite
    # differences of the gyro's prediction: the spin, spline, tilt and the
    # reading's own parameters (w, b and the sensitivity to linear acceleration).
    from wheelcal.estimate.joint.gyro_equations import gyro_prediction

    params, layout = _setup()
    t = np.linspace(-20, 20, 401)
    x0 = layout.pack(params)
    columns = []
    for k in range(layout.size):
        h = 1e-6 * max(1.0, abs(x0[k]))
        if layout.names[k].startswith(("omega", "spin_spline")):
            h = 1e-9  # ϑ grows like t⁴ ω₃: keep the step in the linear range
        up, down = x0.copy(), x0.copy()
        up[k] += h
        down[k] -= h
        diff = gyro_prediction(layout.unpack(up, params), t, layout) - gyro_prediction(
            layout.unpack(down, params), t, layout
        )
        columns.append((diff / (2 * h)).T.reshape(-1))
    jac = np.array(columns)
    expected = jac @ jac.T
    # The likelihood's own JᵀJ: the reading without its prior on G (tested below).
    free = dataclasses.replace(layout, effects=(layout.effects[0], GyroReading(True, None)))
    normal = accumulate_gyro(
        params, t, gyro_prediction(params, t, layout), free, NoiseModel.white(1.0)
    )
    scale = np.sqrt(np.outer(np.diag(expected), np.diag(expected))) + 1e-30
    np.testing.assert_allclose(normal.hessian / scale, expected / scale, atol=1e-5)


def test_the_prior_on_g_adds_its_terms_once():
    # The sensor class's prior on G (GyroReading, σ 0.1 °/s/g by default): cost Σ G²/σ²,
    # gradient G/σ² and information 1/σ² on the six G entries, nothing elsewhere, once
    # whatever the chunking.
    params, layout = _setup()
    t = np.linspace(-20, 20, 2001)
    rng = np.random.default_rng(4)
    gyro = rng.normal(0, 0.002, (t.size, 3))
    free = dataclasses.replace(layout, effects=(layout.effects[0], GyroReading(True, None)))
    noise = NoiseModel.white(0.002)
    with_prior = accumulate_gyro(params, t, gyro, layout, noise, chunk=500)
    without = accumulate_gyro(params, t, gyro, free, noise, chunk=500)
    sigma = 0.1 * np.pi / 180 / 9.80665
    g = params.effect("gyro", 12)[6:]
    rows = np.arange(layout.blocks["effect:gyro"].start + 6, layout.blocks["effect:gyro"].stop)
    extra_h = with_prior.hessian - without.hessian
    expected_h = np.zeros_like(extra_h)
    expected_h[rows, rows] = 1 / sigma**2
    np.testing.assert_allclose(extra_h, expected_h, atol=1e-6 / sigma**2)
    expected_g = np.zeros(layout.size)
    expected_g[rows] = g / sigma**2
    np.testing.assert_allclose(with_prior.gradient - without.gradient, expected_g, atol=1e-6)
    # (the costs hold ~1e11 of prediction against noise: compare at their round-off)
    assert with_prior.cost - without.cost == pytest.approx(
        np.sum(g**2) / sigma**2, abs=1e-14 * with_prior.cost
    )


def test_slots_equal_the_textbook_pieces_and_their_derivatives():
    """cubic_bspline_slots (products, scales folded in) against the plain formulas."""
    from wheelcal.model.effects import cubic_bspline_slots

    t = np.linspace(-15.0, 15.0, 6001)
    start, spacing = -15.0, 5.0
    interval, values, slopes, curves = cubic_bspline_slots(t, start, spacing)
    position = (t - start) / spacing
    np.testing.assert_array_equal(interval, np.floor(position).astype(np.int64))
    x = position - np.floor(position)
    expected_values = [
        (1 - x) ** 3 / 6,
        (3 * x**3 - 6 * x**2 + 4) / 6,
        (-3 * x**3 + 3 * x**2 + 3 * x + 1) / 6,
        x**3 / 6,
    ]
    expected_slopes = [-((1 - x) ** 2) / 2, 1.5 * x**2 - 2 * x, -1.5 * x**2 + x + 0.5, x**2 / 2]
    expected_curves = [1 - x, 3 * x - 2, -3 * x + 1, x]
    np.testing.assert_allclose(values, np.stack(expected_values), rtol=0, atol=1e-15)
    np.testing.assert_allclose(slopes * spacing, np.stack(expected_slopes), rtol=0, atol=1e-14)
    np.testing.assert_allclose(curves * spacing**2, np.stack(expected_curves), rtol=0, atol=1e-14)
