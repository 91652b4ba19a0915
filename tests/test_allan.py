"""The overlapping Allan deviation (issue 28), by reference data set.

* allantools' ``oadev`` (frequency data) on the same samples: the same σ(τ)
  to rounding — the definition, not an approximation of it;
* white noise of known σ_d at f_s: σ(τ) = σ_d / √(f_s τ), and the density
  read at τ = 1 s is σ_d / √f_s (Kalibr's convention), within the estimate's
  own σ (Howe's equivalent degrees of freedom for overlapping white FM);
* a rate random walk of known K: σ(τ) = K √(τ/3) at long τ, and the reported
  K (seen, not a bound) within its σ;
* pooling of disjoint segments is the count-weighted mean of their variances.
"""

import numpy as np
import pytest

from wheelcal.estimate.allan import (
    BIAS_INSTABILITY_FACTOR,
    AllanSums,
    octave_factors,
    overlapping_adev,
)

RATE_HZ = 200.0


def _edf_white(n: int, m: int) -> float:
    """Equivalent dof of an overlapping Allan variance of white FM (Howe, Allan & Barnes 1981)."""
    return (3 * (n - 1) / (2 * m) - 2 * (n - 2) / n) * 4 * m**2 / (4 * m**2 + 5)


def test_the_same_as_allantools_oadev():
    allantools = pytest.importorskip("allantools")
    y = np.random.default_rng(3).normal(0.2, 0.03, size=(3001, 3))
    curve = overlapping_adev(y, RATE_HZ)
    for axis in range(3):
        taus, adev, _, counts = allantools.oadev(
            y[:, axis], rate=RATE_HZ, data_type="freq", taus=curve.tau_s
        )
        np.testing.assert_allclose(taus, curve.tau_s, rtol=1e-12)
        np.testing.assert_allclose(curve.adev[:, axis], adev, rtol=1e-12)
        np.testing.assert_array_equal(curve.counts, counts)


def test_white_noise_gives_its_density_at_one_second():
    sigma_d = 0.02
    n = 80_000  # 400 s
    y = np.random.default_rng(5).normal(9.8, sigma_d, size=(n, 3))
    curve = overlapping_adev(y, RATE_HZ)
    expected = sigma_d / np.sqrt(RATE_HZ * curve.tau_s)
    rel_sigma = 1 / np.sqrt(
        2 * np.array([_edf_white(n + 1, round(t * RATE_HZ)) for t in curve.tau_s])
    )
    usable = curve.counts > 1000
    assert np.all(
        np.abs(curve.adev[usable] / expected[usable, None] - 1) < 4 * rel_sigma[usable, None]
    )
    density, at_one_second = curve.white_noise_density()
    assert at_one_second
    edf = _edf_white(n + 1, round(RATE_HZ))
    assert np.all(np.abs(density / (sigma_d / np.sqrt(RATE_HZ)) - 1) < 4 / np.sqrt(2 * edf))
    # white noise has no floor within the data: the minimum is at the longest τ, a bound
    bias, _, is_floor = curve.bias_instability()
    usable = curve.tau_s * 8 <= curve.duration_s  # ≥ 8 intervals behind a τ
    assert not np.any(is_floor)
    np.testing.assert_allclose(bias * BIAS_INSTABILITY_FACTOR, curve.adev[usable].min(axis=0))
    walk, seen = curve.random_walk()
    assert not np.any(seen) and np.all(walk > 0)  # an upper bound on a walk that is 0


def test_a_random_walk_is_read_off_the_plus_half_slope():
    k = 0.01  # m/s³/√Hz
    n = 200_000  # 1000 s
    steps = np.random.default_rng(9).normal(0.0, k / np.sqrt(RATE_HZ), size=(n, 3))
    y = np.cumsum(steps, axis=0)
    curve = overlapping_adev(y, RATE_HZ, factors=octave_factors(n))
    walk, seen = curve.random_walk()
    assert np.all(seen)
    # The longest τ carries few independent differences: a wide, honest tolerance.
    assert np.all(np.abs(walk / k - 1) < 0.5), walk
    usable = curve.tau_s * 8 <= curve.duration_s  # the τ with ≥ 8 intervals behind them
    bound = np.min(curve.adev[usable] * np.sqrt(3 / curve.tau_s[usable, None]), axis=0)
    np.testing.assert_array_equal(walk, bound)
    # white noise + random walk: a floor between them, not at either end
    white = np.random.default_rng(10).normal(0.0, 0.05, size=(n, 3))
    both = overlapping_adev(y + white, RATE_HZ, factors=octave_factors(n))
    _, tau, is_floor = both.bias_instability()
    assert np.all(is_floor) and np.all((tau > both.tau_s[0]) & (tau < both.tau_s[-1]))


def test_pooled_segments_are_the_count_weighted_variance():
    rng = np.random.default_rng(2)
    a, b = rng.normal(0, 0.02, (900, 3)), rng.normal(5, 0.03, (1500, 3))
    factors = octave_factors(900)
    pooled = AllanSums.combined(
        [AllanSums.of(a, RATE_HZ, factors), AllanSums.of(b, RATE_HZ, factors)]
    )
    curve = pooled.deviation()
    ca, cb = overlapping_adev(a, RATE_HZ, factors), overlapping_adev(b, RATE_HZ, factors)
    expected = np.sqrt(
        (ca.counts[:, None] * ca.adev**2 + cb.counts[:, None] * cb.adev**2)
        / (ca.counts + cb.counts)[:, None]
    )
    np.testing.assert_allclose(curve.adev, expected, rtol=1e-12)
    assert curve.duration_s == pytest.approx(2400 / RATE_HZ)
