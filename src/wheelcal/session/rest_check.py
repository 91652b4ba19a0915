"""The rest check: does the calibration read |a| = g when the wheel stands still.

A rest (:mod:`wheelcal.estimate.rests`) is a static reading of gravity the
fit never saw.  Corrected with the calibration's bias and matrix
(a = M (v − b), M = Γ⁻¹, the ``correction`` block a user applies), its mean
must have length g:

    z = (|M (m − b)| − g) / σ,

σ² combining the rest mean's own σ (coloured noise included) with the
calibration's statistical covariance carried to |a|: with u = M (m − b),
∂|a|/∂m_i = u_i/(γ_i|u|), ∂|a|/∂o_i = −u_i/(γ_i|u|), ∂|a|/∂γ_i = −u_i²/(γ_i|u|).

What it can see: anything outside the null space of eq. (9) — a
nonlinearity, an offset that warms up between the rest and the spin, a
static offset that differs from the dynamic one.  What it cannot see, by
construction: a wrong radius or a wrong assumed gravity.  Both change the
gains, the tilt and o_z exactly so that every reading of eq. (1) — the rests
are readings with ω = 0 — is reproduced, and the corrected rest then reads
the *assumed* g.  Rotation R does not enter |a|.

Each rest is tested two-sided at ``alpha / (number of rests)`` (Bonferroni),
so a clean recording is flagged with probability ≤ ``alpha``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special

from wheelcal.estimate import RestSegment
from wheelcal.estimate.joint import CalibrationResult
from wheelcal.model import AXES


@dataclass(frozen=True)
class RestCheck:
    """One rest's corrected |a| against g."""

    start_s: float
    end_s: float
    norm_mps2: float
    gravity_mps2: float
    std_mps2: float
    z: float
    flagged: bool

    def to_dict(self) -> dict:
        """For the calibration JSON (``fit.rest_checks``)."""
        return {
            "window_s": [self.start_s, self.end_s],
            "norm_mps2": self.norm_mps2,
            "gravity_mps2": self.gravity_mps2,
            "std_mps2": self.std_mps2,
            "z": self.z,
            "flagged": self.flagged,
        }


def check_rests(
    result: CalibrationResult, rests: tuple[RestSegment, ...], alpha: float
) -> tuple[RestCheck, ...]:
    """The corrected |a| of every rest against g (empty when a gain or offset is undetermined)."""
    names = [f"gain_{a}" for a in AXES] + [f"offset_{a}_mps2" for a in AXES]
    index = [result.names.index(n) for n in names]
    cov = result.covariance[np.ix_(index, index)]
    if not rests or not np.all(np.isfinite(cov)):
        return ()
    gain = result.params.sensor.gain
    offset = result.params.sensor.offset_mps2
    g = result.params.gravity_mps2
    # The normal upper quantile (what stats.norm.isf returns, without its ~60 µs of checks).
    z_limit = -special.ndtri(alpha / (2 * len(rests)))
    out = []
    for rest in rests:
        u = (rest.mean_mps2 - offset) / gain
        norm = float(np.linalg.norm(u))
        d_mean = u / (gain * norm)
        jac = np.concatenate([-(u**2) / (gain * norm), -d_mean])  # ∂|a|/∂(γ, o)
        var = float(np.sum((d_mean * rest.mean_std_mps2) ** 2) + jac @ cov @ jac)
        std = float(np.sqrt(max(var, 1e-30)))
        z = (norm - g) / std
        out.append(
            RestCheck(
                rest.start_s, rest.end_s, norm, float(g), std, float(z), bool(abs(z) > z_limit)
            )
        )
    return tuple(out)
