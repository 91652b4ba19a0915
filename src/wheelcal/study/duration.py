"""Precision against recording length and sampling rate: the wheel (CRLB) and six still poses.

Table I's spin is a cubic fitted to 90 s; extrapolated it would not describe
a longer (or shorter) free spin.  For this sweep the wheel slows by quadratic
air drag (the paper's Sec. II-B-1), ω̇ = −c ω², so

    ω(t) = ω_s / (1 + c ω_s t),   c = (ω_s / ω₉₀ − 1) / (90 s · ω_s),

with ω_s and ω₉₀ (the speed after 90 s) close to Table I's spin (9 → 6.4 rad/s).
Over each window the truth is the cubic of eq. (2) fitted to this ω(t) (as
:func:`wheelcal.simulate.presets.hand_spin` does), so the model is exact and
the CRLB at it is what the joint fit attains — which the study checks with a
Monte Carlo at a few (duration, rate) points.  Bench and sensor are Table I's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from wheelcal.model import SpinParams
from wheelcal.simulate import NoiseSpec, Scenario
from wheelcal.study.montecarlo import scenario_bound
from wheelcal.study.static import STATIC_NAMES, StaticPlan, static_bound

#: Parameters the sweep reports (the sensor's, which both methods estimate).
SENSOR_NAMES = STATIC_NAMES


def drag_spin(
    duration_s: float,
    start_radps: float,
    end_radps_at_90s: float,
    theta_start_rad: float = np.deg2rad(30.0),
    degree: int = 3,
) -> SpinParams:
    """Centre-time spin of eq. (2) fitted to a quadratic-drag slow-down (module docstring)."""
    drag = (start_radps / end_radps_at_90s - 1.0) / (90.0 * start_radps)
    t = np.linspace(0.0, duration_s, 4001)
    omega = start_radps / (1.0 + drag * start_radps * t)
    coeffs = np.polynomial.polynomial.polyfit(t, omega, degree)
    return SpinParams(theta0_rad=theta_start_rad, omega_radps=coeffs).shifted(duration_s / 2)


def drag_scenario(
    base: Scenario,
    duration_s: float,
    rate_hz: float,
    sigma_mps2: float,
    start_radps: float,
    end_radps_at_90s: float,
) -> Scenario:
    """``base``'s bench and sensor, a drag spin of ``duration_s``, white noise σ_n."""
    spin = drag_spin(duration_s, start_radps, end_radps_at_90s, degree=base.truth.spin.degree)
    return replace(
        base,
        truth=base.truth.with_changes(spin=spin),
        duration_s=float(duration_s),
        rate_hz=float(rate_hz),
        noise=NoiseSpec(sigma_mps2),
    )


@dataclass(frozen=True, eq=False)
class PrecisionPoint:
    """Predicted σ of offsets and gains (:data:`SENSOR_NAMES` order) at one plan.

    ``static_std`` is NaN when the static plan leaves no still data.
    """

    duration_s: float
    rate_hz: float
    wheel_std: np.ndarray
    static_std: np.ndarray
    static_no_settle_std: np.ndarray


def precision_point(scenario: Scenario, poses: int, settle_s: float) -> PrecisionPoint:
    """Wheel CRLB and static bound (with and without settle time) at one (T, rate).

    ``scenario`` is a :func:`drag_scenario`: its duration, rate, white noise and
    sensor are the static plan's too.
    """
    bound = scenario_bound(scenario)
    wheel = np.array([bound.std_of(n) for n in SENSOR_NAMES])

    def static(settle: float) -> np.ndarray:
        plan = StaticPlan(scenario.duration_s, scenario.rate_hz, poses=poses, settle_s=settle)
        if not plan.feasible:
            return np.full(len(SENSOR_NAMES), np.nan)
        return np.sqrt(np.diag(static_bound(scenario.truth.sensor, plan, scenario.noise)))

    return PrecisionPoint(
        duration_s=scenario.duration_s,
        rate_hz=scenario.rate_hz,
        wheel_std=wheel,
        static_std=static(settle_s),
        static_no_settle_std=static(0.0),
    )


def loglog_slope(x: np.ndarray, y: np.ndarray) -> float:
    """Slope of log y against log x over the finite points (−½ = σ ∝ 1/√x)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(y) & (y > 0)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])
