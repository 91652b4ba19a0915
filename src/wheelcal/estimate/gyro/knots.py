"""How far apart the knots of the wheel-angle spline should be: asked of the gyroscope.

With a gyroscope, ω(t) is measured, so the data say how fast the motion
changes.  The gyro's rate along its principal axis, s(t) = ω_meas·û, is
fitted by uniform cubic B-splines at each candidate spacing (linear least
squares), and the spacing with the smallest Bayesian information criterion

    BIC = N ln(RSS/N) + K ln N

wins: knots dense enough to follow a motor's steps or a push, no denser than
the data support (a free spin-down needs few).  The candidates are powers of
two from ``MAX_SPACING_S`` down to ``MIN_SPACING_S``; the search stops once
finer knots have raised the criterion twice in a row.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solveh_banded

from wheelcal.model import cubic_bspline_slots

MIN_SPACING_S = 0.5
MAX_SPACING_S = 16.0
#: At most this many gyro samples enter the choice (evenly thinned; ω(t) is slow,
#: and the finest spacing still keeps ≥ 10 samples per knot interval of a 5 min window).
MAX_SAMPLES = 6000


@dataclass(frozen=True)
class KnotChoice:
    """The chosen spacing and the criterion of every candidate."""

    spacing_s: float
    bic: dict[float, float]


def choose_knot_spacing(t_s: np.ndarray, gyro_radps: np.ndarray) -> KnotChoice:
    """The knot spacing the gyroscope's rate supports best (valid rows only)."""
    t = np.asarray(t_s, dtype=float)
    g = np.asarray(gyro_radps, dtype=float)
    stride = max(1, t.size // MAX_SAMPLES)
    t, g = t[::stride], g[::stride]
    _, vecs = np.linalg.eigh(g.T @ g)
    s = g @ vecs[:, -1]
    span = float(t[-1] - t[0])
    bic = {}
    spacing = MAX_SPACING_S
    while spacing >= MIN_SPACING_S:
        intervals = max(1, int(np.ceil(span / spacing - 1e-9)))
        count = intervals + 3
        if count < t.size // 2:
            rss = _spline_rss(t, s, float(t[0]), span / intervals, count)
            bic[spacing] = t.size * np.log(max(rss, 1e-300) / t.size) + count * np.log(t.size)
            # Finer knots cost more than they explain twice in a row: the minimum is behind.
            values = list(bic.values())
            if len(values) >= 3 and values[-1] > values[-2] > values[-3]:
                break
        spacing /= 2
    best = min(bic, key=bic.get)
    return KnotChoice(spacing_s=float(best), bic=bic)


def _spline_rss(t: np.ndarray, s: np.ndarray, start_s: float, step_s: float, count: int) -> float:
    """Residual sum of squares of the least-squares uniform cubic B-spline fit of s(t).

    Each sample sees four basis functions (interval j: B_j … B_{j+3}), so the
    Gram matrix is banded (three off-diagonals): accumulated from those four
    values per sample and solved banded — no (count, N) basis matrix, no dense
    solve (a 0.5 s spacing over 5 min has 600 functions).
    """
    interval, values, _, _ = cubic_bspline_slots(t, start_s, step_s)
    rows = interval[None, :] + np.arange(4)[:, None]  # (4, N)
    values[(rows < 0) | (rows >= count)] = 0.0  # functions outside 0 … count − 1
    rows = np.clip(rows, 0, count - 1)
    # Upper band storage of solveh_banded: band[3 − d, k + d] = G[k, k + d].
    band = np.zeros((4, count))
    for m in range(4):
        for d in range(4 - m):
            at = np.minimum(rows[m] + d, count - 1)  # beyond: weight 0 (zeroed above)
            band[3 - d] += np.bincount(at, values[m] * values[m + d], minlength=count)
    rhs = np.zeros(count)
    for m in range(4):
        rhs += np.bincount(rows[m], values[m] * s, minlength=count)
    band[3] += 1e-12 * band[3].sum()  # the dense fit's ridge: 1e-12 · trace(G) on the diagonal
    coef = solveh_banded(band, rhs)
    fitted = np.sum(coef[rows] * values, axis=0)
    return float(np.sum((s - fitted) ** 2))
