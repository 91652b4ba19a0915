"""The field fit's leading samples: low-passed before they are thinned.

The oracle is the signal itself: a wheel's tone and a rim's vibration summed from
their sines, the decimated output against the wheel's tone alone at the kept times.
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.field.decimate import lead_samples
from wheelcal.recording import Recording

RATE_HZ = 120.0
WHEEL_HZ = 8.0  # a car at 15 m/s on a 0.3 m wheel
RIM_HZ = 38.0  # at 120 Hz / 3 it folds onto 2 Hz, inside the wheel's band


def _recording(t: np.ndarray, vibration: float) -> Recording:
    tone = np.sin(2 * np.pi * WHEEL_HZ * t)
    rim = vibration * np.sin(2 * np.pi * RIM_HZ * t + 0.3)
    accel = np.column_stack([tone + rim, 2 * tone, 9.81 + rim])
    gyro = np.column_stack([0.1 * tone, 0.1 * rim, np.full_like(t, 2 * np.pi * WHEEL_HZ)])
    return Recording(t, accel, gyro_radps=gyro)


def test_the_wheels_tone_is_kept_and_the_rims_vibration_is_not_folded_onto_it():
    t = np.arange(0.0, 20.0, 1.0 / RATE_HZ)
    lead = lead_samples(_recording(t, vibration=1.0), 3, 2 * np.pi * WHEEL_HZ)
    tone = np.sin(2 * np.pi * WHEEL_HZ * lead.time_s)
    assert lead.time_s.size >= 0.95 * t.size / 3
    assert np.all(np.isin(lead.time_s, t))  # kept samples' own times: no delay
    np.testing.assert_allclose(lead.accel_mps2[:, 0], tone, atol=3e-4)
    np.testing.assert_allclose(lead.accel_mps2[:, 1], 2 * tone, atol=3e-4)
    np.testing.assert_allclose(lead.accel_mps2[:, 2], 9.81, atol=3e-4)
    np.testing.assert_allclose(lead.gyro_radps[:, 1], 0.0, atol=3e-5)
    # raw thinning folds the rim's 38 Hz onto 2 Hz at full size
    raw = _recording(t, vibration=1.0).thinned(3)
    folded = raw.accel_mps2[:, 0] - np.sin(2 * np.pi * WHEEL_HZ * raw.time_s)
    assert np.std(folded) > 0.5


def test_a_filter_never_reaches_across_a_gap():
    t = np.arange(0.0, 20.0, 1.0 / RATE_HZ)
    keep = np.ones(t.size, bool)
    keep[1000:1003] = False  # a dropped packet
    t = t[keep]
    lead = lead_samples(_recording(t, vibration=0.0), 3, 2 * np.pi * WHEEL_HZ)
    tone = np.sin(2 * np.pi * WHEEL_HZ * lead.time_s)
    np.testing.assert_allclose(lead.accel_mps2[:, 0], tone, atol=3e-4)
    gap = (t[999], t[1000])
    near = np.abs(lead.time_s - 0.5 * sum(gap)) < 0.05
    assert not np.any(near)


def test_no_room_between_the_band_and_its_alias_thins_the_raw_samples():
    t = np.arange(0.0, 20.0, 1.0 / RATE_HZ)
    rec = _recording(t, vibration=1.0)
    fast = 2 * np.pi * 18.0  # a wheel at 18 Hz: 40 Hz − its band overlaps it
    lead = lead_samples(rec, 3, fast)
    np.testing.assert_array_equal(lead.time_s, rec.time_s[::3])
    np.testing.assert_array_equal(lead.accel_mps2, rec.accel_mps2[::3])
    assert lead_samples(rec, 1, fast) is rec
