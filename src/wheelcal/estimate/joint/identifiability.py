"""Is this recording able to tell us the sensor parameters?  Say so with numbers.

Two situations make the sensor parameters unobservable (paper II-C and the
geometry of eq. 1), and a confident-looking number would be a lie:

* a sensor axis lying (nearly) along the wheel axis Z sees only the constant
  g cosα: its gain and offset trade off one-for-one;
* a wheel that hardly slows makes r ω² a constant, indistinguishable from an
  offset along the radial axis X.

The verdict uses the Fisher information of *this* recording (predicted σ at the
estimate), and names the geometric cause when one is present.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model import AXES, CalibrationParams

#: Above these predicted σ a parameter is reported as poorly determined.
GAIN_STD_LIMIT = 5e-3
OFFSET_STD_LIMIT_MPS2 = 0.1
TILT_STD_LIMIT_DEG = 0.5
#: A sensor axis within this angle of the wheel axis is called "along" it.
AXIS_ALIGNMENT_LIMIT_DEG = 10.0
#: ω² must vary by at least this fraction of its mean over the window.
MIN_OMEGA_SQUARED_VARIATION = 0.10


@dataclass(frozen=True)
class Identifiability:
    """Which reported parameters this recording determines, and why not."""

    poorly_determined: tuple[str, ...]
    warnings: tuple[str, ...]

    @property
    def ok(self) -> bool:
        """True when every sensor parameter is determined."""
        return not self.poorly_determined


#: Below this rms ω (rad/s) the spin polynomial does not carry the spin (a field fit's
#: wheel angle comes from the gyroscope): its ω² variation says nothing.
SPINNING_RADPS = 0.1


def check_identifiability(
    params: CalibrationParams,
    t_s: np.ndarray,
    names: tuple[str, ...],
    std: np.ndarray,
) -> Identifiability:
    """Compare predicted σ with useful limits and name the geometric causes."""
    limits = {f"gain_{a}": GAIN_STD_LIMIT for a in AXES}
    limits.update({f"offset_{a}_mps2": OFFSET_STD_LIMIT_MPS2 for a in AXES})
    limits["tilt_deg"] = TILT_STD_LIMIT_DEG
    poor = [n for n, s in zip(names, std, strict=True) if n in limits and not (s <= limits[n])]
    warnings = [
        f"{n} is poorly determined by this recording: predicted σ = {_fmt(s)} (limit {limits[n]:g})"
        for n, s in zip(names, std, strict=True)
        if n in poor
    ]
    rot = params.bench.misalignment.matrix
    for i, axis in enumerate(AXES):
        angle = np.rad2deg(np.arccos(min(1.0, abs(rot[i, 2]))))
        if angle < AXIS_ALIGNMENT_LIMIT_DEG:
            warnings.append(
                f"sensor axis {axis} lies {angle:.1f}° from the wheel axis: it sees only the "
                f"constant g·cos(tilt), so gain_{axis} and offset_{axis}_mps2 trade off "
                "(mount the sensor tilted on the wheel)"
            )
    omega_sq = params.spin.omega_at(np.asarray(t_s)) ** 2
    variation = float(np.ptp(omega_sq) / max(np.mean(omega_sq), 1e-12))
    # (ω ≈ 0 throughout: the spin is not the polynomial's but the gyro's — a field fit)
    if np.mean(omega_sq) > SPINNING_RADPS**2 and variation < MIN_OMEGA_SQUARED_VARIATION:
        warnings.append(
            f"the wheel hardly slowed (ω² varied by {100 * variation:.1f} % over the window): "
            "r·ω² can pass for an offset along the radial axis — record a longer spin-down"
        )
    return Identifiability(poorly_determined=tuple(poor), warnings=tuple(warnings))


def _fmt(value: float) -> str:
    return "∞ (not identifiable)" if not np.isfinite(value) else f"{value:.3g}"
