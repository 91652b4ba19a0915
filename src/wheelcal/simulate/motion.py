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

from wheelcal.model import Kinematics, SpinParams, spin_kinematics


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
    """A spin disturbed by ω̇ += a sinϑ + b cosϑ (ε = √(a²+b²)): an unbalanced wheel.

    ``base`` is the undisturbed motion: a polynomial spin (eq. 2) or any motion
    with ``kinematics(t)`` (a :class:`RateProfile`: a wheel pushed again and again).
    The sensor's own mass on the rim is the commonest imbalance: its torque is
    g sinα · m r sinϑ / I, so ``cos_radps2`` = 0 and ``sin_radps2`` = m g r sinα / I.
    """

    base: SpinParams | RateProfile
    sin_radps2: float
    cos_radps2: float

    def _base(self, t_s: np.ndarray) -> Kinematics:
        if isinstance(self.base, SpinParams):
            return spin_kinematics(self.base, t_s)
        return self.base.kinematics(t_s)

    def kinematics(self, t_s: np.ndarray) -> Kinematics:
        """Integrate ϑ̈ = ω̇_base(t) + a sinϑ + b cosϑ across the sample times."""
        from scipy.integrate import solve_ivp

        t = np.asarray(t_s, float)
        a, b = self.sin_radps2, self.cos_radps2
        base = self._base(t[:1])
        # Start on the forced (once-per-turn) solution so no free oscillation is excited.
        w0 = base.omega_radps[0]
        s, c = np.sin(base.theta_rad[0]), np.cos(base.theta_rad[0])
        y0 = [base.theta_rad[0] - (a * s + b * c) / w0**2, w0 - (a * c - b * s) / w0]
        if isinstance(self.base, SpinParams):
            k = np.arange(1, self.base.degree + 1)
            dot_coef = self.base.omega_radps[1:] * k  # ω̇_base(t) polynomial

            def base_rate_dot(tt):
                return np.polynomial.polynomial.polyval(tt, dot_coef)
        else:

            def base_rate_dot(tt):
                return self.base.kinematics(np.atleast_1d(tt)).omega_dot_radps2

        def rhs(tt, y):
            return [
                y[1],
                float(np.squeeze(base_rate_dot(tt))) + a * np.sin(y[0]) + b * np.cos(y[0]),
            ]

        sol = solve_ivp(rhs, (t[0], t[-1]), y0, t_eval=t, rtol=1e-10, atol=1e-10, method="DOP853")
        theta, omega = sol.y
        omega_dot = base_rate_dot(t) + a * np.sin(theta) + b * np.cos(theta)
        return Kinematics(theta, omega, omega_dot)


@dataclass(frozen=True)
class RateProfile:
    """A wheel driven along any rate law: ω(t) through knots, joined smoothly.

    ω(t) is the shape-preserving cubic (PCHIP) through ``(knot_times_s,
    knot_omega_radps)`` (centred times), constant beyond the end knots; ω̇ is
    its derivative and ϑ its exact antiderivative with ϑ(0) = ``theta0_rad``.
    Two knots a fraction of a second apart make a motor's speed step; a slow
    rise, a hand push or a stop are a few knots each.  This is the motion of a
    *driven* wheel, which eq. (2)'s cubic describes only when it is smooth.
    """

    knot_times_s: tuple[float, ...]
    knot_omega_radps: tuple[float, ...]
    theta0_rad: float = 0.0

    def __post_init__(self) -> None:
        t = np.asarray(self.knot_times_s, float)
        w = np.asarray(self.knot_omega_radps, float)
        if t.ndim != 1 or t.size < 2 or t.size != w.size:
            raise ValueError("need at least two knots, as many rates as times")
        if not np.all(np.diff(t) > 0):
            raise ValueError("knot times must increase")
        object.__setattr__(self, "knot_times_s", tuple(float(x) for x in t))
        object.__setattr__(self, "knot_omega_radps", tuple(float(x) for x in w))

    def kinematics(self, t_s: np.ndarray) -> Kinematics:
        """ϑ, ω, ω̇ at centred times."""
        from scipy.interpolate import PchipInterpolator

        knots = np.asarray(self.knot_times_s)
        rates = np.asarray(self.knot_omega_radps)
        # Flat extensions make ω constant outside the knots (PCHIP would extrapolate).
        pad = 1e6
        rate = PchipInterpolator(
            np.concatenate([[knots[0] - pad], knots, [knots[-1] + pad]]),
            np.concatenate([[rates[0]], rates, [rates[-1]]]),
        )
        angle = rate.antiderivative()
        t = np.asarray(t_s, float)
        theta = self.theta0_rad + angle(t) - angle(0.0)
        return Kinematics(theta, rate(t), rate.derivative()(t))


def steps_profile(
    rng: np.random.Generator,
    duration_s: float,
    omega_radps: float,
    step_fraction: float = 0.1,
    every_s: float = 15.0,
    ramp_s: float = 0.4,
) -> RateProfile:
    """A motor holding the speed, with steps of ±``step_fraction`` every ``every_s``."""
    times, rates = [-duration_s], [omega_radps]
    level = omega_radps
    t = -duration_s / 2 + every_s
    while t < duration_s / 2:
        times.append(t)
        rates.append(level)
        level = omega_radps * (1 + step_fraction * rng.choice([-1.0, 1.0]))
        times.append(t + ramp_s)
        rates.append(level)
        t += every_s
    times.append(duration_s)
    rates.append(level)
    return RateProfile(tuple(times), tuple(rates), float(rng.uniform(-np.pi, np.pi)))


def pushes_profile(
    rng: np.random.Generator,
    duration_s: float,
    pushes: int = 3,
    omega_radps: float = 11.0,
    decay: float = 0.7,
    push_s: float = 0.8,
) -> RateProfile:
    """A hand-spun wheel pushed again ``pushes`` times: spin-downs joined by quick pushes.

    Between pushes the wheel slows by quadratic drag to ``decay`` × its rate;
    each push brings it back to about ``omega_radps`` within ``push_s``.
    """
    segment = duration_s / pushes
    times, rates = [], []
    for k in range(pushes):
        start = -duration_s / 2 + k * segment + (push_s if k else 0.0)
        w0 = omega_radps * rng.uniform(0.9, 1.1)
        drag = (1 / decay - 1) / (w0 * (segment - (push_s if k else 0.0)))
        # Knots every ~0.1 s: the spin-down between pushes is the drag law itself.
        length = segment - (push_s if k else 0.0)
        for tau in np.linspace(0.0, length, max(12, int(length / 0.1))):
            times.append(start + tau)
            rates.append(w0 / (1 + drag * w0 * tau))
    order = np.argsort(times)
    return RateProfile(
        tuple(np.asarray(times)[order]),
        tuple(np.asarray(rates)[order]),
        float(rng.uniform(-np.pi, np.pi)),
    )


def wandering_profile(
    rng: np.random.Generator,
    duration_s: float,
    omega_radps: float = 10.0,
    wander_fraction: float = 0.05,
    every_s: float = 6.0,
) -> RateProfile:
    """A motor whose speed wanders smoothly by ±``wander_fraction`` (a knot every ``every_s``).

    Slow enough (|ω̇| ≪ a push) that it looks like a free spin to the window
    finder, yet no cubic follows it over the whole recording.
    """
    times = np.arange(-duration_s / 2 - every_s, duration_s / 2 + 2 * every_s, every_s)
    rates = omega_radps * (1 + wander_fraction * rng.uniform(-1.0, 1.0, times.size))
    return RateProfile(tuple(times), tuple(rates), float(rng.uniform(-np.pi, np.pi)))
