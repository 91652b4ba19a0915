"""The calibration's front end, made faster, still computes what it computed.

Each fast path is compared with a straightforward computation of the same
quantity (a median per band by ``np.median``, a mean per block by a loop …):
equal, or equal within round-off where the summation order changed.
"""

import dataclasses

import numpy as np

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
    from wheelcal.estimate.noise_reference import HARMONIC_HALF_WIDTH, _Bands

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
