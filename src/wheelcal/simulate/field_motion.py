"""Motions of a wheel in the field: a vehicle's path, or a spin on a fixed axle.

Every law here is a piecewise cubic in time (a scipy ``PPoly``): its value,
first derivative and integral are exact polynomials, so the rigid-body
kinematics built on them (:mod:`wheelcal.simulate.field_kinematics`) are exact
— nothing is differentiated numerically.  Times are recording seconds (the
first sample at t = 0); a law must cover every sample time.

* :class:`VehiclePath` — the hub's speed v(t) ≥ 0 along the wheel's heading
  and the heading's rate ψ̇(t) (yaw about the world vertical).  The wheel
  rolls without slip, which fixes its angle (see :meth:`VehiclePath.state`):

      ω = ψ̇ sin γ − σ v / ρ,    ϑ = ϑ₀ + sin γ (ψ − ψ₀) − σ s / ρ,

  with s(t) = ∫ v dt the distance travelled, γ the camber, σ the side and ρ
  the rolling radius of :class:`~wheelcal.simulate.field_wheel.WheelGeometry`
  (derivation there).
* :class:`AxleSpin` — a fixed axle (the paper's bench, or a vertical wheel
  on a stand): v = 0, ψ constant, and ω(t) any law (rests, a hand push, a
  free spin-down, a brake).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator, PPoly

if TYPE_CHECKING:
    from wheelcal.simulate.field_wheel import WheelGeometry


@dataclass(frozen=True, eq=False)
class SmoothLaw:
    """q(t) as a piecewise cubic, with exact q̇(t) and ∫₀ᵗ q dτ (from the first break).

    Build with :meth:`through` (shape-preserving: no overshoot, flat between
    equal neighbours, so a rest stays exactly at rest) or :meth:`hermite`
    (values and slopes at the knots).
    """

    poly: PPoly

    def __post_init__(self) -> None:
        object.__setattr__(self, "_rate", self.poly.derivative())
        object.__setattr__(self, "_integral", self.poly.antiderivative())

    @classmethod
    def through(cls, times_s, values) -> SmoothLaw:
        """The shape-preserving cubic (PCHIP) through the knots ``(times_s, values)``."""
        t, q = _knots(times_s, values)
        return cls(_as_ppoly(PchipInterpolator(t, q)))

    @classmethod
    def hermite(cls, times_s, values, slopes) -> SmoothLaw:
        """The cubic Hermite law with the given values and derivatives at the knots."""
        t, q = _knots(times_s, values)
        return cls(_as_ppoly(CubicHermiteSpline(t, q, np.asarray(slopes, dtype=float))))

    @property
    def span_s(self) -> tuple[float, float]:
        """First and last break (s): the law is defined between them."""
        return float(self.poly.x[0]), float(self.poly.x[-1])

    @property
    def breaks_s(self) -> np.ndarray:
        """The knots (s), where the second derivative may jump."""
        return np.asarray(self.poly.x)

    def __call__(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(∫ q from the first break, q, q̇) at times ``t_s``."""
        t = np.asarray(t_s, dtype=float)
        lo, hi = self.span_s
        if t.size and (t.min() < lo or t.max() > hi):
            raise ValueError(
                f"times [{t.min():g}, {t.max():g}] s outside the law's [{lo:g}, {hi:g}]"
            )
        return self._integral(t), self.poly(t), self._rate(t)


def _knots(times_s, values) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(times_s, dtype=float)
    q = np.asarray(values, dtype=float)
    if t.ndim != 1 or t.size < 2 or q.shape != t.shape:
        raise ValueError("need at least two knots and one value per knot")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q)) and np.all(np.diff(t) > 0)):
        raise ValueError("knot times must be finite and increasing, values finite")
    return t, q


def _as_ppoly(spline) -> PPoly:
    """A plain PPoly (no extrapolation) with the spline's coefficients."""
    return PPoly(spline.c, spline.x, extrapolate=False)


@dataclass(frozen=True, eq=False)
class MotionState:
    """The wheel's motion at the sample times (each (N,)).

    ``theta_rad``, ``omega_radps``, ``omega_dot_radps2``: the wheel angle ϑ
    relative to its carrier (the knuckle or the stand, which does not spin), its
    rate ω = dϑ/dt and ω̇.  ``heading_rad``, ``yaw_rate_radps``,
    ``yaw_accel_radps2``: the carrier's heading ψ about the world vertical, ψ̇,
    ψ̈.  ``speed_mps``, ``speed_dot_mps2``: the hub's speed v along the heading
    and v̇ (zero on a fixed axle); ``distance_m``: s = ∫ v dt from t = 0.
    """

    theta_rad: np.ndarray
    omega_radps: np.ndarray
    omega_dot_radps2: np.ndarray
    heading_rad: np.ndarray
    yaw_rate_radps: np.ndarray
    yaw_accel_radps2: np.ndarray
    speed_mps: np.ndarray
    speed_dot_mps2: np.ndarray
    distance_m: np.ndarray

    def take(self, rows: np.ndarray) -> MotionState:
        """The state at some of its samples (``rows``: indices or a mask)."""
        return MotionState(*(getattr(self, f.name)[rows] for f in fields(self)))


@dataclass(frozen=True, eq=False)
class VehiclePath:
    """A wheel carried along level ground: hub speed v(t) ≥ 0 and heading rate ψ̇(t).

    ``theta0_rad`` and ``heading0_rad`` are ϑ and ψ at t = 0.  Reversing is out
    of scope (v ≥ 0 is checked at the knots; :meth:`SmoothLaw.through` does not
    overshoot between them).
    """

    speed: SmoothLaw
    yaw_rate: SmoothLaw
    theta0_rad: float = 0.0
    heading0_rad: float = 0.0

    def __post_init__(self) -> None:
        if np.any(self.speed.poly(self.speed.breaks_s) < 0):
            raise ValueError("the hub's speed must be >= 0 (reversing is out of scope)")

    def state(self, t_s: np.ndarray, wheel: WheelGeometry) -> MotionState:
        """ϑ, ω, ω̇ from rolling without slip (module docstring), ψ, v at times ``t_s``.

        ``wheel`` is the :class:`~wheelcal.simulate.field_wheel.WheelGeometry`
        (its camber γ, side σ and rolling radius ρ).
        """
        if wheel.rolling_radius_m is None:
            raise ValueError("a rolling wheel needs its rolling radius")
        rho, side = wheel.rolling_radius_m, wheel.side
        sin_camber = np.sin(wheel.camber_rad)
        distance, speed, speed_dot = self.speed(t_s)
        distance = distance - self.speed(np.zeros(1))[0][0]
        turned, yaw_rate, yaw_accel = self.yaw_rate(t_s)
        turned = turned - self.yaw_rate(np.zeros(1))[0][0]
        theta = self.theta0_rad + sin_camber * turned - side * distance / rho
        omega = sin_camber * yaw_rate - side * speed / rho
        omega_dot = sin_camber * yaw_accel - side * speed_dot / rho
        return MotionState(
            theta_rad=theta,
            omega_radps=omega,
            omega_dot_radps2=omega_dot,
            heading_rad=self.heading0_rad + turned,
            yaw_rate_radps=yaw_rate,
            yaw_accel_radps2=yaw_accel,
            speed_mps=speed,
            speed_dot_mps2=speed_dot,
            distance_m=distance,
        )

    def hub_travel_m(self, start_s: float, end_s: np.ndarray) -> np.ndarray:
        """The hub's world displacement (N, 3) from ``start_s`` to each ``end_s``.

        ∫ v (cos ψ, sin ψ, 0) dτ by adaptive quadrature, split at the knots: an
        independent check of the analytic velocity and acceleration (tests
        only; slow, ~1e-15 m over milliseconds).
        """
        from scipy.integrate import quad

        knots = np.union1d(self.speed.breaks_s, self.yaw_rate.breaks_s)
        turned0 = self.yaw_rate(np.zeros(1))[0][0]

        def velocity(tau: float, axis: int) -> float:
            at = np.array([tau])
            heading = self.heading0_rad + self.yaw_rate(at)[0][0] - turned0
            speed = self.speed(at)[1][0]
            return float(speed * (np.cos(heading) if axis == 0 else np.sin(heading)))

        ends = np.asarray(end_s, dtype=float).reshape(-1)
        out = np.zeros((ends.size, 3))
        for i, end in enumerate(ends):
            lo, hi = sorted((float(start_s), float(end)))
            inside = knots[(knots > lo) & (knots < hi)]
            for axis in (0, 1):
                value, _ = quad(
                    velocity,
                    lo,
                    hi,
                    args=(axis,),
                    points=inside if inside.size else None,
                    epsabs=1e-15,
                    epsrel=1e-14,
                )
                out[i, axis] = value if end >= start_s else -value
        return out


@dataclass(frozen=True, eq=False)
class AxleSpin:
    """A wheel on a fixed axle turning at ω(t) (``rate``), ϑ(0) = ``theta0_rad``.

    ``heading_rad`` is the azimuth of the axle's horizontal part (the physics
    does not depend on it).  ``hand_phases_s`` lists the (start, end) of the
    pushes and brakes, when a hand shakes the wheel (for
    :class:`~wheelcal.simulate.road.VibrationSpec` with ``follows="hands"``);
    ``free_spin_s`` is the free spin-down's window, if there is one.
    """

    rate: SmoothLaw
    theta0_rad: float = 0.0
    heading_rad: float = 0.0
    hand_phases_s: tuple[tuple[float, float], ...] = ()
    free_spin_s: tuple[float, float] | None = None

    def state(self, t_s: np.ndarray, wheel: WheelGeometry | None = None) -> MotionState:
        """ϑ, ω, ω̇ of the spin at times ``t_s``; the hub stands still."""
        del wheel  # a fixed axle's spin does not depend on the geometry
        turned, omega, omega_dot = self.rate(t_s)
        theta = self.theta0_rad + turned - self.rate(np.zeros(1))[0][0]
        zeros = np.zeros_like(theta)
        return MotionState(
            theta_rad=theta,
            omega_radps=omega,
            omega_dot_radps2=omega_dot,
            heading_rad=np.full_like(theta, self.heading_rad),
            yaw_rate_radps=zeros,
            yaw_accel_radps2=zeros,
            speed_mps=zeros,
            speed_dot_mps2=zeros,
            distance_m=zeros,
        )

    def hand_envelope(self, t_s: np.ndarray) -> np.ndarray:
        """1 inside the hand phases, tapered to 0 at their ends (sin²), 0 elsewhere."""
        t = np.asarray(t_s, dtype=float)
        out = np.zeros_like(t)
        for start, end in self.hand_phases_s:
            inside = (t > start) & (t < end)
            out[inside] = np.sin(np.pi * (t[inside] - start) / (end - start)) ** 2
        return out
