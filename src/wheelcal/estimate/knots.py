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

from wheelcal.model.effects import cubic_bspline_basis

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
        step = span / intervals
        basis, _, _ = cubic_bspline_basis(t, float(t[0]), step, intervals + 3)
        if basis.shape[0] < t.size // 2:
            # Normal equations (the Gram matrix is banded and well conditioned).
            gram = basis @ basis.T
            coef = np.linalg.solve(gram + 1e-12 * np.trace(gram) * np.eye(len(gram)), basis @ s)
            rss = float(np.sum((s - coef @ basis) ** 2))
            bic[spacing] = t.size * np.log(max(rss, 1e-300) / t.size) + basis.shape[0] * np.log(
                t.size
            )
            # Finer knots cost more than they explain twice in a row: the minimum is behind.
            values = list(bic.values())
            if len(values) >= 3 and values[-1] > values[-2] > values[-3]:
                break
        spacing /= 2
    best = min(bic, key=bic.get)
    return KnotChoice(spacing_s=float(best), bic=bic)
