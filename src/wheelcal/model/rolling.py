"""A wheel rolling on the ground: rigid-body kinematics of the hub (the ``rolling`` effect).

Scope: a **vertical wheel** (α = 90°, the axle horizontal) **rolling without
slip on level ground**, steered or yawing at a rate ψ̇ about the vertical — a
robot's or a car's wheel with an IMU on it.  A leaning wheel (a bicycle in a
turn, a cambered car wheel) is *not* in scope: its axle is not horizontal, so
gravity leaves the wheel plane and the hub's path is not the contact point's;
lean would have to be a state of its own.  Grades and banked roads are out of
scope too (the vertical is assumed to lie in the wheel plane at all times).

Frames (CONTRACT): bench frame fixed to the wheel, Z the axle, X radial from
the sensor to the hub, Y = Z × X.  With α = 90° the upward unit vector in the
bench frame is u = (cos ϑ, sin ϑ, 0) and the wheel's angular velocity is

    Ω = −ω e_Z + ψ̇ u                                              (bench frame)

(the wheel's spin −ω e_Z, see :mod:`wheelcal.simulate.gyro`, plus the yaw of
the vehicle; u̇ = ω (−sin ϑ, cos ϑ, 0), so the spin still gives ϑ̇ = ω).

Rolling without slip keeps the contact point c = hub − ρ u at rest, with ρ the
rolling radius: v_hub = Ω × ρ u = −ρ ω f, f = e_Z × u = (−sin ϑ, cos ϑ, 0) the
direction of travel.  In the world, f turns with the yaw: ḟ = ψ̇ u × f = ψ̇ e_Z,
so the hub accelerates by

    a_hub = −ρ ω̇ f − ρ ω ψ̇ e_Z          (travel ρ·ω̇; lateral v·ψ̇ along the axle)

The sensor sits at p = −r X from the hub (r its distance from the axle, the
bench radius), and adds Ω̇ × p + Ω × (Ω × p) with, in the bench frame,

    Ω̇ = (ψ̈ cos ϑ − ψ̇ ω sin ϑ,  ψ̈ sin ϑ + ψ̇ ω cos ϑ,  −ω̇).

Eq. (1)'s a = (r ω² + g cos ϑ, r ω̇ + g sin ϑ, 0) holds the spin's share; the
rest, Δa, is this effect (s = sin ϑ, c = cos ϑ):

    Δa_X =  ρ ω̇ s + r ψ̇² s²
    Δa_Y = −ρ ω̇ c − r ψ̇² s c
    Δa_Z = −ρ ω ψ̇ + r ψ̈ s + 2 r ω ψ̇ c

The cross term 2 r ω ψ̇ cos ϑ turns once per turn along the axle, at the
frequency of gravity: a car wheel at 10 m/s (ρ = 0.3 m, ω ≈ 33 rad/s) in a
0.3 rad/s turn with the sensor at r = 0.2 m feels ±4 m/s² of it.

**The yaw rate comes from the gyro**: ψ̇(t) is the gyro's reading along the
upward direction, demodulated with the wheel angle
(:mod:`wheelcal.estimate.gyro.yaw`).  The gyro's scale across the wheel axis is not
calibrated by the spin, so the effect fits a scale κ with ψ̇ = κ ψ̇_gyro:

    parameters  ρ (``radius_m``)  and  κ (``yaw_scale``),

and Δa is the formula above with ρ and κ ψ̇_gyro, κ ψ̈_gyro.  At (ρ, κ) = (0, 0)
Δa = 0: the fixed wheel is a point of the rolling model, so the closed loop can
score-test the effect at a fit that did not declare it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model.effects import Effect
from wheelcal.model.kinematics import Kinematics


@dataclass(frozen=True, eq=False)
class ForceDelta:
    """A change Δa (N, 3) of the bench-frame specific force, and its partials.

    ``d_own`` (k, N, 3) w.r.t. the effect's parameters; ``by_theta``,
    ``by_omega``, ``by_omega_dot`` (N, 3) w.r.t. ϑ, ω, ω̇ (chain rule into the
    spin rows); ``by_radius`` (N, 3) w.r.t. the bench radius r.
    """

    delta: np.ndarray
    d_own: np.ndarray | None = None
    by_theta: np.ndarray | None = None
    by_omega: np.ndarray | None = None
    by_omega_dot: np.ndarray | None = None
    by_radius: np.ndarray | None = None


class Rolling(Effect):
    """A vertical wheel rolling on level ground (see the module docstring for the physics).

    Parameters
    ----------
    time_s:
        Centred times of the yaw-rate series.
    yaw_rate_radps:
        ψ̇_gyro(t), the yaw rate measured by the gyro (rad/s), one per time.
    yaw_accel_radps2:
        ψ̈_gyro(t); default: the series' numerical derivative.
    gyro_yaw_radps:
        (N, 3) share of the yaw in the gyro's samples (its reading of ψ̇ u), or
        ``None``.  A fit with this effect subtracts it from the gyro stream, whose
        own model knows only the spin about the axle.
    yaw_scale_free:
        Fit κ and ε (default).  ``False`` holds κ = 1, ε = 0 and fits ρ alone (parameters:
        ``radius_m``) — a first pass before the yaw is known.
    """

    name = "rolling"
    stage = "force"
    param_names = ("radius_m", "yaw_scale", "yaw_offset_radps")
    description = "wheel rolling on level ground: hub travel ρ·ω̇, turns ρ·ω·ψ̇, Ω cross terms"

    def __init__(
        self,
        time_s: np.ndarray,
        yaw_rate_radps: np.ndarray,
        yaw_accel_radps2: np.ndarray | None = None,
        gyro_yaw_radps: np.ndarray | None = None,
        yaw_scale_free: bool = True,
    ) -> None:
        t = np.asarray(time_s, dtype=float)
        rate = np.asarray(yaw_rate_radps, dtype=float)
        if t.ndim != 1 or t.size < 2 or rate.shape != t.shape or not np.all(np.diff(t) > 0):
            raise ValueError("need increasing times and one yaw rate per time")
        if not np.all(np.isfinite(rate)):
            raise ValueError("the yaw rate must be finite")
        accel = np.gradient(rate, t) if yaw_accel_radps2 is None else yaw_accel_radps2
        accel = np.asarray(accel, dtype=float)
        if accel.shape != t.shape:
            raise ValueError("one yaw acceleration per time")
        if gyro_yaw_radps is not None:
            gyro_yaw_radps = np.asarray(gyro_yaw_radps, dtype=float)
            if gyro_yaw_radps.shape != (t.size, 3):
                raise ValueError("gyro_yaw_radps must be (N, 3), one row per time")
        self.time_s, self.yaw_rate_radps, self.yaw_accel_radps2 = t, rate, accel
        self.gyro_yaw_radps = gyro_yaw_radps
        self.yaw_scale_free = bool(yaw_scale_free)
        if not self.yaw_scale_free:
            self.param_names = ("radius_m",)

    def settings(self) -> dict:
        """The yaw rate's size over the recording (reports only)."""
        return {
            "yaw_rate_rms_radps": float(np.sqrt(np.mean(self.yaw_rate_radps**2))),
            "yaw_rate_max_radps": float(np.max(np.abs(self.yaw_rate_radps))),
        }

    def __eq__(self, other: object) -> bool:
        """Only the same instance: the effect carries its recording's yaw series."""
        return self is other

    def __hash__(self) -> int:
        """Identity hash (see :meth:`__eq__`)."""
        return id(self)

    def yaw(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ψ̇_gyro and ψ̈_gyro at centred times ``t_s``."""
        t = np.asarray(t_s, dtype=float)
        return (
            np.interp(t, self.time_s, self.yaw_rate_radps),
            np.interp(t, self.time_s, self.yaw_accel_radps2),
        )

    def gyro_share(self, t_s: np.ndarray) -> np.ndarray:
        """The yaw's share of the gyro samples at centred times ``t_s`` (zeros if unknown)."""
        t = np.asarray(t_s, dtype=float)
        if self.gyro_yaw_radps is None:
            return np.zeros((t.size, 3))
        return np.column_stack(
            [np.interp(t, self.time_s, self.gyro_yaw_radps[:, i]) for i in range(3)]
        )

    def force_delta(
        self,
        values: np.ndarray,
        t_s: np.ndarray,
        kin: Kinematics,
        radius_m: float,
        jacobian: bool,
    ) -> ForceDelta:
        """Δa of the module docstring, and its partials when ``jacobian``."""
        values = np.asarray(values, dtype=float)
        rho = float(values[0])
        kappa, offset = (float(values[1]), float(values[2])) if self.yaw_scale_free else (1.0, 0.0)
        rate_g, accel_g = self.yaw(t_s)
        yaw, yaw_dot = kappa * rate_g + offset, kappa * accel_g  # ψ̇ = κ ψ̇_gyro + ε
        s, c = np.sin(kin.theta_rad), np.cos(kin.theta_rad)
        w, w_dot = kin.omega_radps, kin.omega_dot_radps2
        r = radius_m
        yaw2 = yaw * yaw
        delta = np.empty((s.size, 3))
        delta[:, 0] = rho * w_dot * s + r * yaw2 * s * s
        delta[:, 1] = -rho * w_dot * c - r * yaw2 * s * c
        delta[:, 2] = -rho * w * yaw + r * yaw_dot * s + 2 * r * w * yaw * c
        if not jacobian:
            return ForceDelta(delta)
        d_own = np.empty((self.size, s.size, 3))
        d_own[0, :, 0] = w_dot * s  # ∂/∂ρ
        d_own[0, :, 1] = -w_dot * c
        d_own[0, :, 2] = -w * yaw
        if self.yaw_scale_free:
            by_yaw = np.column_stack(
                [2 * r * yaw * s * s, -2 * r * yaw * s * c, -rho * w + 2 * r * w * c]
            )
            d_own[1] = by_yaw * rate_g[:, None]  # ∂/∂κ through ψ̇ and ψ̈
            d_own[1, :, 2] += r * s * accel_g
            d_own[2] = by_yaw  # ∂/∂ε
        by_theta = np.empty_like(delta)
        by_theta[:, 0] = rho * w_dot * c + 2 * r * yaw2 * s * c
        by_theta[:, 1] = rho * w_dot * s - r * yaw2 * (c * c - s * s)
        by_theta[:, 2] = r * yaw_dot * c - 2 * r * w * yaw * s
        by_omega = np.zeros_like(delta)
        by_omega[:, 2] = -rho * yaw + 2 * r * yaw * c
        by_omega_dot = np.zeros_like(delta)
        by_omega_dot[:, 0] = rho * s
        by_omega_dot[:, 1] = -rho * c
        by_radius = np.empty_like(delta)
        by_radius[:, 0] = yaw2 * s * s
        by_radius[:, 1] = -yaw2 * s * c
        by_radius[:, 2] = yaw_dot * s + 2 * w * yaw * c
        return ForceDelta(delta, d_own, by_theta, by_omega, by_omega_dot, by_radius)
