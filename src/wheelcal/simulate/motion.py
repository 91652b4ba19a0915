"""Physical wheel motions for the simulator, beyond the model's polynomial spin.

The closed loop must be tested on data that contain effects nobody declared,
so the simulator can drive the wheel by physics instead of eq. (2):

* :class:`DragSpin` — pure quadratic air drag, ω̇ = −c ω|ω|, in closed form
  (ω = ω_s / (1 + c|ω_s|τ), ϑ = ϑ_s + sign(ω_s) ln(1 + c|ω_s|τ)/c);
* :class:`ImbalancedSpin` — a polynomial spin plus a once-per-turn torque,
  ϑ̈ = ω̇₀(t) + ε sin(ϑ + φ), integrated numerically to high accuracy.

Both give :class:`~wheelcal.model.kinematics.Kinematics` at centred times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model.kinematics import Kinematics, spin_kinematics
from wheelcal.model.parameters import SpinParams


@dataclass(frozen=True)
class DragSpin:
    """Quadratic-drag spin-down from ω_start to ω_end over the window (both signed)."""

    omega_start_radps: float
    omega_end_radps: float
    duration_s: float
    theta0_rad: float = 0.0

    def __post_init__(self) -> None:
        if not (0 < abs(self.omega_end_radps) < abs(self.omega_start_radps)):
            raise ValueError("need 0 < |omega_end| < |omega_start|")
        if np.sign(self.omega_end_radps) != np.sign(self.omega_start_radps):
            raise ValueError("the wheel does not reverse during a spin-down")

    @property
    def drag_per_rad(self) -> float:
        """The drag constant c of ω̇ = −c ω|ω| (1/rad)."""
        return (1 / abs(self.omega_end_radps) - 1 / abs(self.omega_start_radps)) / self.duration_s

    def kinematics(self, t_s: np.ndarray) -> Kinematics:
        """ϑ, ω, ω̇ at centred times (t = 0 at the window centre)."""
        c = self.drag_per_rad
        w_s = self.omega_start_radps
        tau = np.asarray(t_s, float) + self.duration_s / 2  # time since the window start
        grow = 1 + c * abs(w_s) * tau
        omega = w_s / grow
        theta = self.theta0_rad + np.sign(w_s) * np.log(grow) / c
        omega_dot = -c * omega * np.abs(omega)
        return Kinematics(theta, omega, omega_dot)


@dataclass(frozen=True)
class ImbalancedSpin:
    """A polynomial spin (eq. 2) disturbed by ω̇ += a sinϑ + b cosϑ (ε = √(a²+b²))."""

    base: SpinParams
    sin_radps2: float
    cos_radps2: float

    def kinematics(self, t_s: np.ndarray) -> Kinematics:
        """Integrate ϑ̈ = ω̇_base(t) + a sinϑ + b cosϑ across the sample times."""
        from scipy.integrate import solve_ivp

        t = np.asarray(t_s, float)
        a, b = self.sin_radps2, self.cos_radps2
        base = spin_kinematics(self.base, t[:1])
        # Start on the forced (once-per-turn) solution so no free oscillation is excited.
        w0 = base.omega_radps[0]
        s, c = np.sin(base.theta_rad[0]), np.cos(base.theta_rad[0])
        y0 = [base.theta_rad[0] - (a * s + b * c) / w0**2, w0 - (a * c - b * s) / w0]
        k = np.arange(1, self.base.degree + 1)
        dot_coef = self.base.omega_radps[1:] * k  # ω̇_base(t) polynomial

        def rhs(tt, y):
            return [
                y[1],
                np.polynomial.polynomial.polyval(tt, dot_coef)
                + a * np.sin(y[0])
                + b * np.cos(y[0]),
            ]

        sol = solve_ivp(rhs, (t[0], t[-1]), y0, t_eval=t, rtol=1e-10, atol=1e-10, method="DOP853")
        theta, omega = sol.y
        omega_dot = (
            np.polynomial.polynomial.polyval(t, dot_coef) + a * np.sin(theta) + b * np.cos(theta)
        )
        return Kinematics(theta, omega, omega_dot)
