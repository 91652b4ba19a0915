"""The residual folded on the wheel angle: its mean per bin of ϑ mod 360°.

Effects the model lacks often repeat every turn (an unbalanced wheel, a sensor
off its measured radius): against time they hide in the noise, folded on ϑ
they line up.  The session ``.rrd`` draws 5° bins; the calibration JSON keeps
10° bins (``fit.residual_by_wheel_angle``) for the batch overview.
"""

from __future__ import annotations

import numpy as np


def binned_mean_by_angle(
    theta_rad: np.ndarray, values: np.ndarray, bins: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean of ``values`` (N, 3) in ``bins`` equal bins of ϑ mod 2π.

    Returns
    -------
    centres_deg, mean, count
        Centres in degrees of the bins that hold samples, the per-axis mean
        there (B, 3) and the number of samples in each.
    """
    wrapped = np.mod(np.asarray(theta_rad, dtype=float), 2 * np.pi)
    index = np.minimum((wrapped * (bins / (2 * np.pi))).astype(np.int64), bins - 1)
    count = np.bincount(index, minlength=bins)
    sums = np.column_stack(
        [np.bincount(index, weights=values[:, k], minlength=bins) for k in range(3)]
    )
    filled = count > 0
    centres_deg = (np.arange(bins) + 0.5) * (360.0 / bins)
    return centres_deg[filled], sums[filled] / count[filled, None], count[filled]


def residual_by_wheel_angle(
    theta_rad: np.ndarray, residual_mps2: np.ndarray, bin_deg: float = 10.0
) -> dict:
    """The residual's mean per ``bin_deg`` of ϑ mod 360° (JSON-ready; bins without samples omitted).

    Effects that repeat every turn line up here while they hide in the noise
    against time (see :mod:`wheelcal.viz.session_rrd`); the batch overview
    draws these profiles for every session.
    """
    bins = round(360.0 / bin_deg)
    centres, mean, count = binned_mean_by_angle(theta_rad, np.asarray(residual_mps2), bins)
    return {
        "bin_deg": 360.0 / bins,
        "centres_deg": [float(c) for c in centres],
        "mean_mps2": [[float(v) for v in row] for row in mean],
        "samples": [int(c) for c in count],
    }
