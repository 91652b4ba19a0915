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
