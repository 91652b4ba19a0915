"""Decimation that never aliases the wheel's rotation.

Several steps work on a thinned copy of the samples to save time (the
closed-form start, the first LM stage, the planner's Fisher information).
Taking every k-th sample keeps ``rate/k`` samples per second; the rotating
gravity signal turns at f = |ω|/2π, so thinning is safe only while
``rate/(k·f) ≥ samples_per_turn``.  A fixed target count (e.g. "3,000
samples") aliases long recordings: a 1 h spin at 200 Hz thinned to 3,000
samples keeps 0.8 samples per second of a 1.6 Hz turn.  Every thinning goes
through :func:`decimation_stride`.
"""

from __future__ import annotations

import numpy as np

#: Samples per wheel turn that a thinned copy keeps at the fastest rate.
SAMPLES_PER_TURN = 16.0


def decimation_stride(
    rate_hz: float, omega_max_radps: float, samples_per_turn: float = SAMPLES_PER_TURN
) -> int:
    """Largest stride that keeps ≥ ``samples_per_turn`` samples per turn at ω_max."""
    turn_hz = abs(omega_max_radps) / (2 * np.pi)
    if not turn_hz > 0:
        return 1
    return max(1, int(np.floor(rate_hz / (samples_per_turn * turn_hz))))


def thinning_stride(
    samples: int,
    target_samples: int,
    rate_hz: float,
    omega_max_radps: float,
    samples_per_turn: float = SAMPLES_PER_TURN,
) -> int:
    """Stride toward ``target_samples`` samples, but never below ``samples_per_turn`` per turn."""
    wanted = max(1, samples // max(target_samples, 1))
    return min(wanted, decimation_stride(rate_hz, omega_max_radps, samples_per_turn))
