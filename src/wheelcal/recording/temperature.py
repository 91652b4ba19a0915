"""The sensor's temperature, put onto the accelerometer's sample times.

A temperature comes either per sample (``wheelcal.AccelBatch``'s
``temperature_c``) or as its own topic with its own stamps and rate (ROS 2
``sensor_msgs/msg/Temperature``, typically 1–100 Hz).  Either way it is a
series of (stamp, °C) readings, and :func:`temperature_at` interpolates it
linearly onto the accelerometer's (cleaned) stamps, holding the first and
last reading beyond the ends.  Temperature changes over seconds to minutes,
so linear interpolation between readings loses nothing that matters.

Like the gyro, the temperature is auxiliary: a defect drops it (with a note
in ``Recording.notes``) and never refuses the recording:

* NaN/inf readings are dropped (noted); the rest is interpolated across them;
* readings outside −60…150 °C are not degrees Celsius of a working sensor
  (kelvin? raw counts?): the channel is dropped, with the median in the note;
* stamps that do not overlap the samples at all (another clock): dropped;
* the readings end (or start) well inside the recording: held, and noted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PLAUSIBLE_C = (-60.0, 150.0)


@dataclass(frozen=True, eq=False)
class TemperatureReadings:
    """A series of temperature readings on their own clock, for :func:`temperature_at`."""

    #: Where the readings come from (e.g. ``"topic /imu/temperature"``), for notes.
    what: str
    #: int64 stamps, ns, any order, repeats allowed.
    stamp_ns: np.ndarray
    #: °C, NaN allowed.
    values_c: np.ndarray


def temperature_at(
    what: str,
    stamp_ns: np.ndarray,
    temperature_c: np.ndarray,
    sample_ns: np.ndarray,
) -> tuple[np.ndarray | None, tuple[str, ...]]:
    """Temperatures (°C) at the accelerometer's stamps, or None, with notes.

    Parameters
    ----------
    what:
        Where the readings come from (e.g. ``"topic /imu/temperature"``), for notes.
    stamp_ns, temperature_c:
        The readings: int64 stamps (any order, repeats allowed) and °C (NaN allowed).
    sample_ns:
        The accelerometer's sorted stamps (int64).

    Returns
    -------
    temperature : ndarray (M,) or None
    notes : tuple of str
    """
    t = np.asarray(stamp_ns, dtype=np.int64).reshape(-1)
    temp = np.asarray(temperature_c, dtype=float).reshape(-1)
    samples = np.asarray(sample_ns, dtype=np.int64)
    notes: list[str] = []
    finite = np.isfinite(temp)
    if not np.any(finite):
        return None, (f"temperature ({what}): no finite reading; ignored",)
    if not np.all(finite):
        missing = int((~finite).sum())
        notes.append(
            f"temperature ({what}): {missing} of {temp.size} readings missing or NaN; "
            "interpolated across"
        )
        t, temp = t[finite], temp[finite]
    median = float(np.median(temp))
    lo, hi = PLAUSIBLE_C
    if not lo <= median <= hi:
        guess = " (kelvin?)" if 200 < median < 450 else ""
        return None, (
            *notes,
            f"temperature ({what}): the median reading {median:.4g} is not a sensor's "
            f"temperature in °C{guess}; ignored",
        )
    # Sorted unique stamps, repeated stamps averaged.
    order = np.argsort(t, kind="stable")
    t, temp = t[order], temp[order]
    unique_t, first, counts = np.unique(t, return_index=True, return_counts=True)
    values = np.add.reduceat(temp, first) / counts
    start, end = int(samples[0]), int(samples[-1])
    if unique_t[-1] < start or unique_t[0] > end:
        span = f"{(unique_t[0] - start) * 1e-9:+.3f} … {(unique_t[-1] - start) * 1e-9:+.3f} s"
        return None, (
            *notes,
            f"temperature ({what}): its stamps ({span} from the first sample) do not "
            f"overlap the samples (0 … {(end - start) * 1e-9:.3f} s): another clock? ignored",
        )
    step = float(np.median(np.diff(unique_t))) if unique_t.size > 1 else 0.0
    uncovered = max(0, int(unique_t[0]) - start) + max(0, end - int(unique_t[-1]))
    if uncovered > max(1e9, 2 * step):
        covered_s = (min(end, int(unique_t[-1])) - max(start, int(unique_t[0]))) * 1e-9
        notes.append(
            f"temperature ({what}): readings cover {covered_s:.3f} s of the "
            f"{(end - start) * 1e-9:.3f} s recording; held at the end values beyond"
        )
    # Relative float ns are exact below 2**53 ns (104 days).
    out = np.interp((samples - start).astype(float), (unique_t - start).astype(float), values)
    return out, tuple(notes)
