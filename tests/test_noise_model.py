import numpy as np
import pytest

from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.simulate import NoiseSpec


def test_estimated_ar_model_recovers_the_low_pass_filter():
    spec = NoiseSpec((0.05, 0.08, 0.1), bandwidth_hz=20.0)
    x = spec.sample(100_000, 200.0, np.random.default_rng(0))
    nm = NoiseModel.estimate(x)
    truth = spec.ar_polynomial(200.0)
    for a in nm.ar_polynomials:
        assert np.allclose(a[:3], truth, atol=0.03)
    assert np.allclose(nm.marginal_std_mps2, spec.std, rtol=0.03)
    # Low-pass noise has more power at low frequency: fewer effective samples.
    assert np.all(nm.effective_sample_fraction < 0.5)


def test_white_noise_gets_order_zero_or_negligible_colour():
    x = NoiseSpec(0.08).sample(50_000, 200.0, np.random.default_rng(1))
    nm = NoiseModel.estimate(x)
    assert np.allclose(nm.long_run_std_mps2, 0.08, rtol=0.05)
    assert np.allclose(nm.effective_sample_fraction, 1.0, atol=0.06)


def test_whitening_gives_unit_variance_uncorrelated_errors():
    rng = np.random.default_rng(2)
    spec = NoiseSpec(0.08, bandwidth_hz=30.0)
    x = spec.sample(60_000, 200.0, rng)
    mix = np.array([[1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.0, 0.3, 1.0]])
    x = x @ mix.T  # correlated across axes
    nm = NoiseModel.estimate(x)
    r, _ = nm.whiten(x)
    assert np.allclose(np.cov(r), np.eye(3), atol=0.03)
    assert abs(np.corrcoef(r[0, 1:], r[0, :-1])[0, 1]) < 0.02


def test_whitening_a_jacobian_matches_whitening_its_columns():
    rng = np.random.default_rng(3)
    nm = NoiseModel.estimate(NoiseSpec(0.08, bandwidth_hz=25.0).sample(20_000, 200.0, rng))
    jac = rng.standard_normal((4, 3, 500))
    _, jw = nm.whiten(np.zeros((500, 3)), jac)
    for k in range(4):
        col, _ = nm.whiten(jac[k].T)
        assert np.allclose(jw[k], col)


@pytest.mark.parametrize(
    "orders", [(1, 1, 1), (2, 0, 1), (3, 3, 3), (1, 6, 2), (9, 4, 0), (40, 12, 35)]
)
def test_whitening_a_jacobian_equals_lfilter_then_the_inverse_cholesky_factor(orders):
    # Independent of noise_model's code paths (one 3 × 3 product per tap for short
    # filters, the per-axis FIR then L⁻¹ for long ones): scipy's lfilter per column and
    # axis, the first p outputs dropped, then L⁻¹ of the innovations' covariance.
    from scipy.signal import lfilter

    rng = np.random.default_rng(sum(orders))
    polys = tuple(np.r_[1.0, rng.normal(0.0, 0.3, k)] for k in orders)
    mixing = rng.normal(size=(3, 3))
    cov = mixing @ mixing.T + np.eye(3)
    nm = NoiseModel(polys, cov)
    jac = rng.standard_normal((5, 3, 400))
    _, jw = nm.whiten(np.zeros((400, 3)), jac)
    p = max(orders)
    filtered = np.stack([lfilter(a, [1.0], jac[:, i, :], axis=-1) for i, a in enumerate(polys)], 1)
    expected = np.linalg.inv(np.linalg.cholesky(cov)) @ filtered[:, :, p:]
    assert jw.shape == (5, 3, 400 - p)
    np.testing.assert_allclose(jw, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("orders", [(2, 0, 5), (40, 12, 35)])
def test_whitening_a_residual_equals_lfilter_then_the_inverse_cholesky_factor(orders):
    # The residual's FIR (a scaled add per tap, numpy's convolution past 32 taps) against
    # scipy's lfilter, as for the Jacobian above.
    from scipy.signal import lfilter

    rng = np.random.default_rng(7 + sum(orders))
    polys = tuple(np.r_[1.0, rng.normal(0.0, 0.1, k)] for k in orders)
    cov = np.diag([1.0, 2.0, 0.5])
    nm = NoiseModel(polys, cov)
    residual = rng.standard_normal((600, 3))
    r, _ = nm.whiten(residual)
    p = max(orders)
    filtered = np.stack([lfilter(a, [1.0], residual[:, i]) for i, a in enumerate(polys)])
    expected = np.linalg.inv(np.linalg.cholesky(cov)) @ filtered[:, p:]
    np.testing.assert_allclose(r, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
