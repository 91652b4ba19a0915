"""The leading passes' samples: every k-th, low-passed first (nothing aliased onto the wheel).

The field fit's leading passes run on about ``LEAD_SAMPLES`` of a drive's samples.
Taken as every k-th raw sample, a road's vibration folds onto the wheel's own
frequencies: a car's rim shakes at 25–55 Hz and 0.4–1.2 m/s², and at 120 Hz / 3 that
band lands on 0–15 Hz, where gravity turns.  There it is noise the full rate's AR model
would have told apart from the signal, and the thinned fit came out 4–12 σ (of the
full fit's σ) from the fit to every sample — three thinnings of one drive as far from
each other — so the passes that should lead the final fit to its camber led it astray,
and the final fit's own passes had to walk the rest of the way.  Low-passed first (a
linear-phase FIR, flat to 1e-4 over the wheel's band), every k-th sample keeps the
wheel's signal and loses only what lies above it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import signal

from wheelcal.recording import Recording

#: The FIR's ripple over the wheel's band and its rejection above (dB).
RIPPLE_DB = 80.0
#: The wheel's band: its fastest turn rate times this, plus ``BAND_MARGIN_HZ``.
BAND_FACTOR = 1.1
BAND_MARGIN_HZ = 1.0
#: A filtered sample is kept only where its taps span no gap longer than this many
#: sample intervals (a dropped packet, a clipped stretch): a filter across a gap mixes
#: times it does not know.
GAP_INTERVALS = 1.5


def lead_samples(window: Recording, stride: int, fastest_radps: float) -> Recording:
    """Every ``stride``-th sample of ``window``, low-passed to the wheel's band first.

    The band reaches ``BAND_FACTOR`` × the fastest turn rate (Hz) + ``BAND_MARGIN_HZ``;
    the filter rejects all that would alias into it.  Where the decimated rate leaves
    no room between the band and its alias, or too few gap-free samples remain (half),
    the raw thinning (:meth:`Recording.thinned`).
    """
    stride = int(stride)
    if stride <= 1:
        return window
    t = window.time_s
    dt = float(np.median(np.diff(t)))
    rate_hz = 1.0 / dt
    band_hz = BAND_FACTOR * abs(float(fastest_radps)) / (2.0 * np.pi) + BAND_MARGIN_HZ
    stop_hz = rate_hz / stride - band_hz  # the lowest frequency that folds into the band
    if stop_hz <= band_hz:
        return window.thinned(stride)
    taps_n, beta = signal.kaiserord(RIPPLE_DB, (stop_hz - band_hz) / (0.5 * rate_hz))
    taps_n |= 1  # odd: a delay of whole samples
    if taps_n >= t.size // 2:
        return window.thinned(stride)
    taps = signal.firwin(taps_n, 0.5 * (band_hz + stop_hz), window=("kaiser", beta), fs=rate_hz)
    half = taps_n // 2
    centres = np.arange(half, t.size - half, stride)
    span = t[centres + half] - t[centres - half]
    centres = centres[span <= (taps_n - 1 + GAP_INTERVALS - 1.0) * dt]
    if centres.size < 0.5 * t.size / stride:
        return window.thinned(stride)

    def filtered(x: np.ndarray) -> np.ndarray:
        out = np.empty((centres.size, x.shape[1]))
        for i in range(x.shape[1]):
            out[:, i] = np.convolve(x[:, i], taps, mode="valid")[centres - half]
        return out

    gyro = window.gyro_radps
    temperature = window.temperature_c
    return dataclasses.replace(
        window,
        time_s=t[centres],
        accel_mps2=filtered(window.accel_mps2),
        gyro_radps=None if gyro is None else filtered(gyro),
        temperature_c=None if temperature is None else temperature[centres],
    )
