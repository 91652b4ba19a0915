"""The paper's Table I (Sec. IV-A): truth, and mean ± σ of 60 runs at σ_n = 0.08 and 0.2 m/s².

Transcribed from the paper into wheelcal's reported names and units (ϑ₀ in
rad, ω_k in rad/s^(k+1), angles in degrees, offsets in m/s²).  The motion
parameters are in the paper's time origin, the first sample (see
:mod:`wheelcal.simulate.presets`); θ, φ, ψ are ``euler_1/2/3_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PaperRow:
    """One row of Table I: true value and (mean, σ) per noise level."""

    parameter: str
    symbol: str
    display_unit: str
    display_scale: float  # reported unit → the paper's display unit
    truth: float
    at_sigma: dict[float, tuple[float, float]]


_DEG = np.deg2rad(1.0)

#: Rows of Table I in the paper's order.
TABLE1_ROWS: tuple[PaperRow, ...] = (
    PaperRow("omega3_radps4", "ω₃", "µrad/s⁴", 1e6, 2e-6,
             {0.08: (2.000e-6, 0.002e-6), 0.2: (2.000e-6, 0.004e-6)}),
    PaperRow("omega2_radps3", "ω₂", "µrad/s³", 1e6, 500e-6,
             {0.08: (500.0e-6, 0.3e-6), 0.2: (499.9e-6, 0.5e-6)}),
    PaperRow("omega1_radps2", "ω₁", "mrad/s²", 1e3, -90e-3,
             {0.08: (-90.00e-3, 0.01e-3), 0.2: (-90.00e-3, 0.02e-3)}),
    PaperRow("omega0_radps", "ω₀", "rad/s", 1.0, 9.0,
             {0.08: (9.000, 0.0001), 0.2: (9.000, 0.0002)}),
    PaperRow("theta0_rad", "ϑ₀", "°", 1 / _DEG, 30 * _DEG,
             {0.08: (29.99 * _DEG, 0.03 * _DEG), 0.2: (29.94 * _DEG, 0.07 * _DEG)}),
    PaperRow("tilt_deg", "α", "°", 1.0, 45.0, {0.08: (45.00, 0.01), 0.2: (45.01, 0.03)}),
    PaperRow("euler_1_deg", "θ", "°", 1.0, 30.0, {0.08: (29.99, 0.03), 0.2: (29.93, 0.07)}),
    PaperRow("euler_2_deg", "φ", "°", 1.0, 20.0, {0.08: (19.99, 0.02), 0.2: (19.97, 0.03)}),
    PaperRow("euler_3_deg", "ψ", "°", 1.0, 25.0, {0.08: (25.00, 0.08), 0.2: (25.04, 0.16)}),
    PaperRow("gain_x", "γ_x", "", 1.0, 0.9, {0.08: (0.8999, 0.0001), 0.2: (0.8998, 0.0003)}),
    PaperRow("gain_y", "γ_y", "", 1.0, 1.0, {0.08: (1.0000, 0.0004), 0.2: (0.9999, 0.0009)}),
    PaperRow("gain_z", "γ_z", "", 1.0, 1.1, {0.08: (1.1005, 0.0007), 0.2: (1.1026, 0.0017)}),
    PaperRow("offset_x_mps2", "o_x", "m/s²", 1.0, 1.0,
             {0.08: (1.001, 0.005), 0.2: (1.006, 0.010)}),
    PaperRow("offset_y_mps2", "o_y", "m/s²", 1.0, -1.0,
             {0.08: (-1.001, 0.014), 0.2: (-1.008, 0.027)}),
    PaperRow("offset_z_mps2", "o_z", "m/s²", 1.0, 1.0,
             {0.08: (0.996, 0.009), 0.2: (1.006, 0.019)}),
)  # fmt: skip

#: Noise levels of Table I (m/s²).
TABLE1_SIGMAS_MPS2 = (0.08, 0.2)
#: Realisations per level in the paper.
PAPER_REALISATIONS = 60


def paper_value(parameter: str, sigma_mps2: float) -> tuple[float, float] | None:
    """The paper's (mean, σ) of ``parameter`` at ``sigma_mps2``, or ``None`` if not in Table I."""
    for row in TABLE1_ROWS:
        if row.parameter == parameter:
            for level, value in row.at_sigma.items():
                if abs(level - sigma_mps2) < 1e-9:
                    return value
    return None
