"""Exactly where the fit goes when a quantity it holds fixed is wrong (eq. 9–13, all orders).

Write eq. (1) and (6) with k(t) = (ω², ω̇, 0) and c(t) = (cos ϑ, sin ϑ, 0):

    v(t) = o + Γ R (r k(t) + g sin α c(t) + g cos α e_Z).

For a given spin and mounting R, axis i of the data determines only three
numbers: γ_i r, γ_i g sin α and o_i + γ_i R_iZ g cos α — the last because
a_Z = g cos α is a constant, like the offset (paper II-C).  Any (r, g, α, Γ, o)
with the same three products gives *identical* data; eq. (9)–(13) is the
special case of a fixed g.  So when the fit holds some of r, α, g at wrong
values, the noise-free fit lands exactly on the solution of

    Γ' r' = Γ r,   Γ' g' sin α' = Γ g sin α,   o' + Γ' R e_Z g' cos α' = o + Γ R e_Z g cos α

with the fixed quantities at their assumed values:

* radius mode (r', g' assumed): Γ' = Γ r/r',  sin α' = (r' g sin α)/(r g'),
  o' = o + Γ R e_Z g cos α − Γ' R e_Z g' cos α'  (no solution when sin α' > 1:
  near a vertical wheel a radius error cannot be absorbed);
* tilt and vertical modes (α', g' assumed): Γ' = Γ g sin α/(g' sin α'),
  r' = r Γ/Γ', and o' as above.

A vertical wheel mis-levelled by δ has α = 90° − δ while the fit assumes 90°:
gains come out × cos δ (−δ²/2, zero to first order) and offsets move by
g sin δ along Γ R e_Z (≈ 0.17 m/s² per degree).  At a tilt α the same error
moves the gains to first order, by cot α · δ.

A sample clock that stretches time stamps by (1 + ε) reads ω/(1 + ε) and
ω̇/(1 + ε)², so the data look like a radius r(1 + ε)² with the spin coefficients
ω_k/(1 + ε)^(k+1): a radius error to the fit (absorbed by r itself in the
tilt and vertical modes).

Because the map is exact, it gives the systematic shifts to every order; the
joint fit's linearised budget (:mod:`wheelcal.estimate.joint.systematic`) is its first
derivative.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint import report_transform
from wheelcal.model import BenchParams, CalibrationParams, ParameterLayout, SensorParams, SpinParams

#: The fixed quantities a fit can get wrong, with the unit of their error.
ERROR_UNITS = {"radius": "m", "tilt": "deg", "gravity": "m/s^2", "sample_clock": "ppm"}


@dataclass(frozen=True)
class AssumedErrors:
    """Errors of the fixed quantities: assumed value − true value (clock: stretch in ppm)."""

    radius_m: float = 0.0
    tilt_deg: float = 0.0
    gravity_mps2: float = 0.0
    clock_ppm: float = 0.0

    @classmethod
    def single(cls, source: str, error: float) -> AssumedErrors:
        """One source (a name of :data:`ERROR_UNITS`) in its unit."""
        field = {
            "radius": "radius_m",
            "tilt": "tilt_deg",
            "gravity": "gravity_mps2",
            "sample_clock": "clock_ppm",
        }
        if source not in field:
            raise ValueError(f"unknown systematic source {source!r}; choose from {sorted(field)}")
        return cls(**{field[source]: error})


class NotAbsorbable(ArithmeticError):
    """No parameter set reproduces the data with the assumed values (sin α' > 1)."""


def absorbed_fit(
    assumed: CalibrationParams, geometry: str, errors: AssumedErrors
) -> tuple[CalibrationParams, CalibrationParams]:
    """The true bench behind ``assumed`` and where a noise-free fit converges.

    Parameters
    ----------
    assumed:
        The planned parameters; r, α and g here are the values the fit assumes
        where they are fixed (``radius`` mode: r and g; ``tilt``/``vertical``: α and g).
    geometry:
        ``radius``, ``tilt`` or ``vertical`` (which quantities are fixed).
    errors:
        Assumed − true of each fixed quantity; quantities the mode fits are
        ignored (they are not assumed).

    Returns
    -------
    (truth, fitted):
        The true parameters (fixed quantities at assumed − error, sensor and
        mounting as planned) and the fitted ones (module docstring).
    """
    if geometry not in ("radius", "tilt", "vertical"):
        raise ValueError(f"unknown geometry {geometry!r}")
    bench = assumed.bench
    radius_known = geometry == "radius"
    r_true = bench.radius_m - (errors.radius_m if radius_known else 0.0)
    alpha_true = bench.tilt_rad - (0.0 if radius_known else np.deg2rad(errors.tilt_deg))
    g_true = assumed.gravity_mps2 - errors.gravity_mps2
    truth = CalibrationParams(
        spin=assumed.spin,
        bench=BenchParams(tilt_rad=alpha_true, radius_m=r_true, misalignment=bench.misalignment),
        sensor=assumed.sensor,
        gravity_mps2=g_true,
        effects=assumed.effects,
    )
    # Clock stretch (1 + ε): the fit sees ω_k/(1+ε)^(k+1) and an effective radius r(1+ε)².
    stretch = 1.0 + 1e-6 * errors.clock_ppm
    powers = stretch ** np.arange(1, assumed.spin.degree + 2)
    seen_spin = SpinParams(assumed.spin.theta0_rad, assumed.spin.omega_radps / powers)
    r_seen = r_true * stretch**2

    gain = assumed.sensor.gain
    z_column = bench.misalignment.matrix[:, 2]  # R e_Z
    g_fit = assumed.gravity_mps2  # g is always assumed
    if radius_known:
        r_fit = bench.radius_m
        gain_fit = gain * r_seen / r_fit
        sin_fit = r_fit * g_true * np.sin(alpha_true) / (r_seen * g_fit)
        if abs(sin_fit) > 1.0:
            raise NotAbsorbable(
                "no tilt absorbs this error (sin α' > 1): the wheel is too close to vertical "
                "for radius mode, the fit will not match the data"
            )
        alpha_fit = np.arcsin(sin_fit)
        if np.cos(alpha_true) < 0:  # keep the branch of the truth
            alpha_fit = np.pi - alpha_fit
    else:
        alpha_fit = bench.tilt_rad
        gain_fit = gain * g_true * np.sin(alpha_true) / (g_fit * np.sin(alpha_fit))
        r_fit = r_seen * gain[0] / gain_fit[0]
    offset_fit = (
        assumed.sensor.offset_mps2
        + gain * z_column * g_true * np.cos(alpha_true)
        - gain_fit * z_column * g_fit * np.cos(alpha_fit)
    )
    fitted = CalibrationParams(
        spin=seen_spin,
        bench=BenchParams(tilt_rad=alpha_fit, radius_m=r_fit, misalignment=bench.misalignment),
        sensor=SensorParams(offset_mps2=offset_fit, gain=gain_fit),
        gravity_mps2=g_fit,
        effects=assumed.effects,
    )
    return truth, fitted


def reported_shift(
    assumed: CalibrationParams, geometry: str, layout: ParameterLayout, errors: AssumedErrors
) -> np.ndarray:
    """Fitted − true reported parameters (names of ``report_transform``) for these errors."""
    truth, fitted = absorbed_fit(assumed, geometry, errors)
    _, true_values, _ = report_transform(truth, layout)
    _, fit_values, _ = report_transform(fitted, layout)
    shift = fit_values - true_values
    # Unchanged parameters (R, ϑ₀, …) differ only by round-off: report them as 0.
    return np.where(np.abs(shift) < 1e-12 * np.maximum(1.0, np.abs(true_values)), 0.0, shift)
