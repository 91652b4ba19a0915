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

Both take the signal as rows (3, n), one contiguous row per axis: numpy is
slow on (n, 3) columns (:mod:`wheelcal.estimate.joint.columns`).
"""

from __future__ import annotations

import numpy as np

from wheelcal.estimate.joint.columns import row_gram


def rotating_phase(h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unwrapped angle (sign chosen so it mostly increases) and radius of h (3, n) in its plane."""
    radius = np.sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2])
    strong = radius > np.median(radius)
    _, vectors = np.linalg.eigh(row_gram(np.compress(strong, h, axis=1)))  # = h[:, strong]
    z = vectors[:, 2] @ h + 1j * (vectors[:, 1] @ h)
    phase = np.unwrap(np.angle(z))
    if phase[-1] < phase[0]:
        phase = -phase
    return phase, np.abs(z)


def revolution_mean(v: np.ndarray, ramp: np.ndarray, max_half: int) -> np.ndarray:
    """Mean of v (3, n) over one revolution centred on each sample (phase within ±π).

    ``ramp`` is a monotone phase, so each window is one index range; windows
    are capped at ``max_half`` samples each side (at rest the phase does not
    advance and a revolution would never end).
    """
    index = np.arange(ramp.size)
    lo = np.maximum(np.searchsorted(ramp, ramp - np.pi, side="left"), index - max_half)
    hi = np.minimum(np.searchsorted(ramp, ramp + np.pi, side="right"), index + max_half + 1)
    total = np.zeros((v.shape[0], v.shape[1] + 1))
    np.cumsum(v, axis=1, out=total[:, 1:])
    # np.take: the same as total[:, hi], several times faster along axis 1.
    return (np.take(total, hi, axis=1) - np.take(total, lo, axis=1)) / (hi - lo)
