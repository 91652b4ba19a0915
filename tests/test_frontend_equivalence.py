"""The calibration's front end, made faster, still computes what it computed.

Each fast path is compared with a straightforward computation of the same
quantity (a median per band by ``np.median``, a mean per block by a loop …):
equal, or equal within round-off where the summation order changed.
"""

import dataclasses

import numpy as np
import pytest

from wheelcal.recording import Recording


def test_rate_is_computed_once_and_belongs_to_each_recording():
    """The cached median rate of a window, a selection or a replaced copy is its own."""
    t = np.concatenate([np.arange(100) * 0.01, 1.0 + np.arange(100) * 0.002])
    recording = Recording(t, np.zeros((200, 3)))
    assert recording.rate_hz == float(1.0 / np.median(np.diff(t)))
    assert recording.rate_hz is recording.rate_hz  # cached: the same object
    assert np.isclose(recording.window(1.0, 2.0).rate_hz, 500.0)
    assert np.isclose(recording.select(np.arange(200) < 100).rate_hz, 100.0)
    assert np.isclose(dataclasses.replace(recording, time_s=2 * t).rate_hz, 50.0)


def _floor_sum_by_loop(power, band, between):
    """The band floors of noise_reference._Bands, one np.median per band."""
    total = 0.0
    for k in range(int(band[-1]) + 1):
        in_band = band == k
        ref = in_band & between
        if not np.any(ref):
            ref = (np.abs(band - k) <= 1) & between
            if not np.any(ref):
                total += float(power[in_band].sum())
                continue
        total += float(in_band.sum() * np.median(power[ref])) / np.log(2.0)
    return total


def test_band_floors_are_the_medians_of_each_band():
    """Bands of uneven size (odd, even, partial) and one without bins between orders."""
    from wheelcal.session.noise_reference import HARMONIC_HALF_WIDTH, _Bands

    rng = np.random.default_rng(5)
    for bins, turns in ((8193, 100.3), (1001, 37.0), (4097, 12.7)):
        order = np.arange(bins) / turns
        band = np.round(order).astype(np.int64)
        between = np.abs(order - band) > HARMONIC_HALF_WIDTH
        power = rng.exponential(size=bins) * (1 + band)  # floors differ band by band
        fast = _Bands(band, between).floor_sum(power)
        # (the same medians; only the final sum's order differs)
        assert np.isclose(fast, _floor_sum_by_loop(power, band, between), rtol=1e-13, atol=0)
    # Band 1 has no bins between the orders: it borrows its neighbours' median.
    band = np.array([0, 0, 0, 0, 1, 1, 2, 2, 2, 2, 2])
    between = np.array([1, 1, 0, 1, 0, 0, 1, 0, 1, 1, 1], dtype=bool)
    power = rng.exponential(size=band.size)
    fast = _Bands(band, between).floor_sum(power)
    assert np.isclose(fast, _floor_sum_by_loop(power, band, between), rtol=1e-13, atol=0)


def test_column_statistics_equal_numpys():
    from wheelcal.estimate.joint.columns import centred_rows, column_means, row_gram

    x = np.random.default_rng(6).normal(3.0, 2.0, size=(5001, 3))
    mean = column_means(x)
    assert np.allclose(mean, x.mean(axis=0), rtol=1e-14, atol=0)
    rows = centred_rows(x, mean)
    assert rows.shape == (3, 5001) and rows.flags.c_contiguous
    assert np.array_equal(rows, (x - mean).T)
    assert np.allclose(row_gram(rows), rows @ rows.T, rtol=1e-13, atol=0)
    assert np.array_equal(row_gram(rows), row_gram(rows).T)


def test_difference_stds_equal_numpys():
    from wheelcal.estimate.joint.columns import difference_stds

    x = np.cumsum(np.random.default_rng(8).normal([0.1, -2.0, 5.0], [1.0, 0.3, 7.0], (5001, 3)), 0)
    expected = np.std(np.diff(x, axis=0), axis=0)
    assert np.allclose(difference_stds(x), expected, rtol=1e-13, atol=0)
    assert np.allclose(difference_stds(x[:, ::-1]), expected[::-1], rtol=1e-13, atol=0)


def test_legendre_normal_equations_give_polyfits_polynomial():
    """The phase polynomial and the trend, as polyfit and lstsq gave them."""
    from wheelcal.estimate.joint.initial import _legendre_fit

    rng = np.random.default_rng(7)
    tau = np.linspace(-1.0, 1.0, 4341)
    phase = 700.0 * tau - 9.0 * tau**2 + 0.3 * tau**3 + 0.01 * rng.standard_normal(tau.size)
    legendre = np.polynomial.legendre.legvander(tau, 6)
    gram = legendre.T @ legendre
    coef = np.polynomial.legendre.leg2poly(_legendre_fit(legendre, gram, 4, phase))
    expected = np.polynomial.polynomial.polyfit(tau, phase, 4)
    assert np.allclose(coef, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    y = rng.standard_normal((tau.size, 2)) + np.cos(3 * tau)[:, None]
    fitted = legendre @ _legendre_fit(legendre, gram, 6, y)
    by_svd = legendre @ np.linalg.lstsq(legendre, y, rcond=None)[0]
    assert np.allclose(fitted, by_svd, rtol=0, atol=1e-13)


def _dominant_frequency_by_fftfreq(u, rate_hz):
    """The turn rate as the closed-form start computed it before: full FFT axis, (n, 2) input."""
    z = u[:, 0] + 1j * u[:, 1]
    nfft = 1 << int(np.ceil(np.log2(z.size)))
    spec = np.abs(np.fft.fft(z - z.mean(), nfft))
    freqs = np.fft.fftfreq(nfft, d=1.0 / rate_hz)
    spec[0] = 0.0
    return float(abs(freqs[int(np.argmax(spec))]))


def test_dominant_frequency_of_the_wheel_plane_either_direction():
    from wheelcal.estimate.joint.initial import _dominant_frequency, _plane_signal

    rng = np.random.default_rng(8)
    t = np.arange(17364) / 200.0
    for turn_hz in (1.43, -0.7, 37.1):  # the sign: the direction of turning
        angle = 2 * np.pi * turn_hz * t
        v = np.column_stack([3 * np.cos(angle), 2 * np.sin(angle), 0.01 * t + 9.0])
        v += 0.05 * rng.standard_normal(v.shape)
        found = _dominant_frequency(_plane_signal(v), 200.0)
        assert abs(found - abs(turn_hz)) <= 200.0 / 32768
        u = (v - v.mean(axis=0)) @ np.linalg.eigh(np.cov(v.T))[1][:, 1:]
        assert found == _dominant_frequency_by_fftfreq(u, 200.0)
        assert found == _dominant_frequency(np.ascontiguousarray(u.T), 200.0)


def test_window_search_low_pass_is_scipys_sosfiltfilt():
    """The zero-phase filter with its start state solved once gives sosfiltfilt's numbers."""
    from scipy import signal

    from wheelcal.session.window import _lowpass

    rng = np.random.default_rng(9)
    for rate, size in ((50.0, 4501), (20.0, 200), (16.0, 10)):
        rows = rng.standard_normal((3, size)).cumsum(axis=1)
        design = _lowpass(min(8.0, 0.4 * rate), rate)
        expected = signal.sosfiltfilt(design.sos, rows, axis=-1)
        assert np.array_equal(design.filtfilt(rows), expected)
        by_columns = signal.sosfiltfilt(design.sos, rows.T, axis=0)  # as the search filtered
        assert np.array_equal(design.filtfilt(rows).T, by_columns)
    with pytest.raises(ValueError, match="padlen"):  # too short to pad: as scipy says
        design.filtfilt(rows[:, :9])


def test_rotating_phase_and_revolution_mean_on_rows():
    from wheelcal.estimate.joint.rotating import revolution_mean, rotating_phase

    rng = np.random.default_rng(10)
    t = np.arange(3000) / 50.0
    angle = 2 * np.pi * (1.2 * t - 0.004 * t**2)
    v = np.vstack([np.cos(angle), np.sin(angle), 0.002 * t + 0.3])
    v += 0.01 * rng.standard_normal(v.shape)
    phase, radius = rotating_phase(v)
    # As computed on (n, 3) columns: the same radius, the same phase up to a constant.
    h = v.T
    strong = np.linalg.norm(h, axis=1) > np.median(np.linalg.norm(h, axis=1))
    vectors = np.linalg.eigh(h[strong].T @ h[strong])[1]
    z = h @ vectors[:, 2] + 1j * (h @ vectors[:, 1])
    expected = np.unwrap(np.angle(z))
    expected = expected if expected[-1] > expected[0] else -expected
    assert np.allclose(radius, np.abs(z), rtol=1e-13, atol=0)
    assert np.allclose(np.diff(phase), np.diff(expected), rtol=0, atol=1e-12)
    assert np.allclose(phase - phase[0], angle - angle[0], rtol=0, atol=0.1)
    # The mean over one revolution (capped at max_half samples each side), sample by sample.
    ramp = np.maximum.accumulate(phase)
    mean = revolution_mean(v, ramp, 40)
    for i in (0, 17, 1500, 2999):
        inside = np.abs(ramp - ramp[i]) <= np.pi
        inside &= np.abs(np.arange(ramp.size) - i) <= 40
        assert np.allclose(mean[:, i], v[:, inside].mean(axis=1), rtol=0, atol=1e-12)


def test_rest_blocks_and_segments_as_numpy_computes_them():
    from wheelcal.estimate.rests import _segment, block_statistics

    rng = np.random.default_rng(11)
    v = rng.normal([0.1, -0.2, 9.8], 0.05, size=(2013, 3))
    means, stds = block_statistics(v, 20)
    blocks = v[:2000].reshape(100, 20, 3)
    assert means.shape == stds.shape == (100, 3)
    assert np.allclose(means, blocks.mean(axis=1), rtol=1e-14, atol=0)
    assert np.allclose(stds, blocks.std(axis=1, ddof=1), rtol=1e-12, atol=0)
    segment = _segment(np.arange(2013) / 200.0, v)
    assert np.allclose(segment.mean_mps2, v.mean(axis=0), rtol=1e-14, atol=0)
    expected_std = np.std(v - v.mean(axis=0), axis=0, ddof=1)
    assert np.allclose(segment.noise_std_mps2, expected_std, rtol=1e-13, atol=0)


def test_noise_model_innovation_covariance_is_the_filtered_residuals_gram():
    from wheelcal.estimate.joint.noise_model import NoiseModel
    from wheelcal.model.ar_process import fir_filter
    from wheelcal.simulate import NoiseSpec

    rng = np.random.default_rng(12)
    x = NoiseSpec(0.08, bandwidth_hz=25.0).sample(20_000, 200.0, rng)
    x = x @ np.array([[1.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.2, 0.3, 1.0]]).T + 0.3
    model = NoiseModel.estimate(x)
    p = model.order
    assert p > 0
    centred = x - x.mean(axis=0)
    innov = np.column_stack(
        [fir_filter(a, centred[:, i])[p:] for i, a in enumerate(model.ar_polynomials)]
    )
    expected = innov.T @ innov / innov.shape[0]
    expected += np.eye(3) * 1e-18 * np.trace(expected)
    assert np.allclose(model.innovation_cov, expected, rtol=1e-12, atol=0)


def test_start_regression_is_least_squares_when_well_or_ill_posed():
    """Step 3 of the start: normal equations when well posed, the SVD when ω² hardly varies."""
    from wheelcal.estimate.joint.initial import _regression

    rng = np.random.default_rng(13)
    t = np.linspace(-40.0, 40.0, 4341)
    theta = 9.0 * t - 0.05 * t**2
    for omega, well_posed in ((9.0 - 0.1 * t, True), (9.0 + 1e-7 * t, False)):
        design = np.column_stack([np.ones_like(t), omega**2, np.cos(theta), np.sin(theta)])
        v = design @ rng.normal(size=(4, 3)) + 0.08 * rng.standard_normal((t.size, 3))
        coef, xtx_inv = _regression(design, v)
        expected = np.linalg.lstsq(design, v, rcond=None)[0]
        assert np.allclose(design @ coef, design @ expected, rtol=0, atol=1e-9)
        if well_posed:  # the coefficients and the inverse too
            assert np.allclose(coef, expected, rtol=1e-9, atol=1e-12)
            assert np.allclose(xtx_inv @ (design.T @ design), np.eye(4), atol=1e-9)
        else:  # the SVD's minimum-norm solution
            assert np.array_equal(coef, expected)


def _yule_walker_by_toeplitz(x, max_order):
    """AR(p) by AIC, each order's Yule–Walker equations solved directly."""
    from scipy.linalg import solve_toeplitz

    n = x.size
    acov = np.array([x[: n - k] @ x[k:] for k in range(max_order + 1)]) / n
    best, best_aic = np.ones(1), n * np.log(acov[0])
    for k in range(1, max_order + 1):
        a = solve_toeplitz(acov[:k], -acov[1 : k + 1])
        aic = n * np.log(acov[0] + a @ acov[1 : k + 1]) + 2 * k
        if aic < best_aic:
            best, best_aic = np.concatenate([[1.0], a]), aic
    return best


def test_levinson_recursion_gives_the_yule_walker_solution_of_the_aic_order():
    from wheelcal.estimate.joint.noise_model import _yule_walker_aic
    from wheelcal.simulate import NoiseSpec

    rng = np.random.default_rng(14)
    for bandwidth in (None, 60.0, 25.0, 8.0):
        spec = NoiseSpec(0.08) if bandwidth is None else NoiseSpec(0.08, bandwidth_hz=bandwidth)
        x = spec.sample(17_000, 200.0, rng)[:, 0]
        x = x - x.mean()
        for max_order in (6, 10):
            fast = _yule_walker_aic(x, max_order)
            expected = _yule_walker_by_toeplitz(x, max_order)
            assert fast.size == expected.size
            assert np.allclose(fast, expected, rtol=0, atol=1e-10)
    assert np.array_equal(_yule_walker_aic(np.zeros(100), 6), [1.0])


def test_start_of_a_short_window_skips_the_full_rate_spectrum(monkeypatch):
    """Below 2 × 4000 samples nothing is thinned, whatever the turn rate: no spectrum needed."""
    from wheelcal.estimate.joint import initial
    from wheelcal.estimate.joint.decimation import thinning_stride
    from wheelcal.estimate.joint.fit import JointFit
    from wheelcal.simulate import simulate, table1

    # The stride the spectrum would have chosen: 1 at any turn rate.
    for omega_radps in (0.0, 1.0, 10.0, 1e3, 1e6):
        assert thinning_stride(7999, 4000, 200.0, omega_radps) == 1
    recording = simulate(table1(), np.random.default_rng(15)).recording
    short = recording.window(10.0, 10.0 + 7999 / 200.0)  # 8000 samples
    shorter = recording.window(10.0, 10.0 + 7998 / 200.0)  # 7999 samples
    assert short.samples == 8000 and shorter.samples == 7999

    def no_spectrum(*args):
        raise AssertionError("the full-rate spectrum was computed")

    monkeypatch.setattr(initial, "_plane_signal", no_spectrum)
    with pytest.raises(AssertionError, match="full-rate spectrum"):
        JointFit().start(short)  # 8000 samples could be thinned 2×: the rate decides
    guess = JointFit().start(shorter).params
    assert abs(guess.bench.tilt_rad - np.deg2rad(45.0)) < 0.05  # a usable start


def test_column_rms_equals_numpys():
    from wheelcal.estimate.joint.columns import column_rms

    x = np.random.default_rng(4).normal(0.3, 2.0, size=(5001, 3)) * [1.0, 1e-3, 1e3]
    expected = np.sqrt(np.mean(x**2, axis=0))
    assert np.allclose(column_rms(x), expected, rtol=1e-13, atol=0)
    assert np.allclose(column_rms(x[::-2]), np.sqrt(np.mean(x[::-2] ** 2, axis=0)), rtol=1e-13)
