"""The rotating part of the signal: its phase, and what is left after a revolution's mean.

In the sensor frame the gravity component g sin α (cos ϑ We_X + sin ϑ We_Y)
rotates in the plane of the wheel while everything else varies slowly (or
jumps when the wheel is pushed).  Two tools serve the window search and the
closed-form start, for any motion:

* :func:`rotating_phase` — the unwrapped angle of a signal in its main plane
  (sign chosen so it mostly increases) and its radius;
* :func:`revolution_mean` — the mean over one revolution centred on each
  sample: subtracted, it cancels the rotation's slow companions exactly
  (r ω², offsets, g cos α) whatever ω(t) does, where a polynomial trend would
  ring at a push.
"""

from __future__ import annotations

import numpy as np


def rotating_phase(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unwrapped angle (sign chosen so it mostly increases) and radius of h in its main plane."""
    radius = np.linalg.norm(h, axis=1)
    strong = radius > np.median(radius)
    _, vectors = np.linalg.eigh(h[strong].T @ h[strong])
    z = h @ vectors[:, 2] + 1j * (h @ vectors[:, 1])
    phase = np.unwrap(np.angle(z))
    if phase[-1] < phase[0]:
        phase = -phase
    return phase, np.abs(z)


def revolution_mean(v: np.ndarray, ramp: np.ndarray, max_half: int) -> np.ndarray:
    """Mean of v over one revolution centred on each sample (phase within ±π).

    ``ramp`` is a monotone phase, so each window is one index range; windows
    are capped at ``max_half`` samples each side (at rest the phase does not
    advance and a revolution would never end).
    """
    index = np.arange(ramp.size)
    lo = np.maximum(np.searchsorted(ramp, ramp - np.pi, side="left"), index - max_half)
    hi = np.minimum(np.searchsorted(ramp, ramp + np.pi, side="right"), index + max_half + 1)
    total = np.vstack([np.zeros((1, 3)), np.cumsum(v, axis=0)])
    return (total[hi] - total[lo]) / (hi - lo)[:, None]
