"""Angles averaged as angles: the start angle θ₀ and the mounting's Euler angles wrap.

A mean of 179° and −179° is 180°, not 0°: before any mean, spread or outlier
test over sessions, each value is moved by whole turns to lie within half a
turn of the sessions' circular mean, atan2(Σ sin, Σ cos) — the values the
statistics then see are the same angles, unwrapped.  For angles that do not
wrap in the data (a spread of a few degrees far from ±180°) nothing changes.
"""

from __future__ import annotations

import math

import numpy as np

#: Parameters that are angles, with their period (a contract name's unit says which).
ANGLE_PERIODS = {
    "theta0_rad": 2.0 * math.pi,
    "euler_1_deg": 360.0,
    "euler_2_deg": 360.0,
    "euler_3_deg": 360.0,
}


def period_of(name: str) -> float | None:
    """The period of parameter ``name`` if it is an angle that wraps, else None."""
    return ANGLE_PERIODS.get(name)


def circular_mean(values, period: float) -> float:
    """The circular mean of angles with this period (NaN ignored; NaN if none)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan
    phase = 2.0 * math.pi * v / period
    return float(
        math.atan2(np.mean(np.sin(phase)), np.mean(np.cos(phase))) * period / (2 * math.pi)
    )


def unwrapped(values, period: float) -> np.ndarray:
    """``values`` moved by whole periods to within half a period of their circular mean.

    The arithmetic mean, std and outlier tests of the result are those of the
    angles; NaN stays NaN.
    """
    v = np.asarray(values, dtype=float)
    centre = circular_mean(v, period)
    if not math.isfinite(centre):
        return v.copy()
    return centre + (v - centre + 0.5 * period) % period - 0.5 * period


def as_angles(name: str, values) -> np.ndarray:
    """The values of parameter ``name``, unwrapped if it is an angle (else as they are)."""
    period = period_of(name)
    v = np.asarray(values, dtype=float)
    return v if period is None else unwrapped(v, period)
