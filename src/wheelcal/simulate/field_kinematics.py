"""Exact rigid-body kinematics of a wheel on level ground or on a fixed axle.

Written in the world frame from the geometry below, without wheelcal's model
code (:mod:`wheelcal.model`): the tests compare it with eq. (1) of the paper
(:func:`wheelcal.model.evaluate`) and with the rolling effect
(:mod:`wheelcal.model.rolling`), which were derived independently.

Geometry
--------
* **World**: x, y horizontal, z up (e_z); level ground; gravity g⃗ = −g e_z.
  The accelerometer senses the specific force f = p̈ − g⃗.
* **Carrier**: the wheel turns on a carrier that does not spin — the knuckle of
  a rigid vehicle, or a bench's stand.  The carrier is fixed to the chassis at
  constant camber γ and toe 0, so its attitude is a yaw ψ(t) about the world
  vertical followed by the fixed camber; no roll, pitch or suspension travel
  (road vibration is added separately, as a small translation).  ψ is the
  *wheel's own* heading: the chassis's yaw for a car's rear wheel, the chassis's
  yaw plus the steering angle for a steered one.  Forward f = (cos ψ, sin ψ, 0),
  left l = e_z × f.
* **Side** σ = +1 for a wheel on the vehicle's left, −1 on its right.
* **Camber** γ ∈ [0°, 90°): the wheel plane leans from the vertical by γ, its
  top toward the vehicle (inboard: a wheelchair's 18°, a car's negative camber),
  so the axle's upper end is outboard and the CONTRACT's Z (the axle, on the
  side that points upward) is

      Z = σ cos γ l + sin γ e_z,      α = ∠(Z, e_z) = 90° − γ.

  (At γ = 0 both ends are level; Z is taken outboard.)  The in-plane "up"
  (steepest ascent within the wheel plane) is u = cos γ e_z − σ sin γ l, and
  w = Z × u = σ f.
* **Bench frame**: X = cos ϑ u − sin ϑ w, Y = sin ϑ u + cos ϑ w = Z × X, Z.
  At ϑ = 0, X = u (the sensor, at −r X, is at the bottom); dX/dϑ = −Y as the
  CONTRACT requires; ϑ is the wheel's angle *relative to its carrier*.  A(t) =
  [X Y Z] maps bench to world.
* **Hub** H: the centre of the wheel, on the axle in the wheel's mid-plane.
  **Rolling radius ρ**: the wheel is a thin rigid disc of radius ρ about H in
  its own plane; it touches the ground at its lowest point C = H − ρ u (so H is
  at height ρ cos γ).  ρ is the loaded rolling radius of the no-slip relation
  below; a tyre's cross-section (which moves C sideways with γ) is out of scope.
* **Sensor**: at p = −r X + h Z from H — r from the axle (the bench radius), h
  along the axle from the mid-plane (a sensor on a hub's outer face).
* **Rolling without slip**: the hub travels along the wheel's heading,
  Ḣ = v f with v ≥ 0 (no side slip), and the material point at C is at rest.

Derivation
----------
The carrier turns at ψ̇ e_z and the wheel relative to it at −ω Z (dX/dt =
−ω Y = −ω Z × X), so

    Ω = ψ̇ e_z − ω Z,     Ż = ψ̇ e_z × Z,     Ω̇ = ψ̈ e_z − ω̇ Z − ω ψ̇ e_z × Z.

No slip: 0 = Ḣ + Ω × (C − H) = v f − ρ Ω × u.  With Z × u = σ f and
e_z × u = σ sin γ f, Ω × u = σ (ψ̇ sin γ − ω) f, hence

    σ v = ρ (ψ̇ sin γ − ω),   i.e.   ω = ψ̇ sin γ − σ v / ρ

(a cambered wheel in a turn turns on its carrier by ψ̇ sin γ besides v/ρ: it
is Ω's axle component that rolls).  The hub: Ḣ = v f, Ḧ = v̇ f + v ψ̇ l
(ḟ = ψ̇ l).  The sensor, q = A p:

    Ṗ = v f + Ω × q,     P̈ = Ḧ + Ω̇ × q + Ω × (Ω × q),     a = Aᵀ (P̈ + g e_z),

a in the bench frame; the accelerometer reads o + Γ R a, the gyro the body rate
Aᵀ Ω (:mod:`wheelcal.simulate.gyro`).  This module evaluates exactly these
world-frame vectors.  In the bench frame (c = cos ϑ, s = sin ϑ; n = Aᵀe_z =
(cos γ c, cos γ s, sin γ); Aᵀf = σ(−s, c, 0); Aᵀl = σ(−sin γ c, −sin γ s, cos γ);
Ω = ψ̇ n − ω e_Z = (Ω_x, Ω_y, Ω_z), Ω_z = ψ̇ sin γ − ω) they expand, for h = 0, to

    a_X = g cos γ c − σ v̇ s − σ v ψ̇ sin γ c + r (ψ̇² cos²γ s² + Ω_z²)
    a_Y = g cos γ s + σ v̇ c − σ v ψ̇ sin γ s + r (ω̇ − ψ̈ sin γ) − r ψ̇² cos²γ s c
    a_Z = g sin γ + σ v ψ̇ cos γ + r cos γ (ψ̈ s + ω ψ̇ c − ψ̇ c Ω_z)

and the axle offset h adds (a point on the axle moves with the carrier, not
with the spin: no ω in it)

    h (ψ̈ cos γ s + ψ̇² sin γ cos γ c,  −ψ̈ cos γ c + ψ̇² sin γ cos γ s,  −ψ̇² cos²γ).

Checks: a fixed axle (v = ψ̇ = 0) gives eq. (1) with α = 90° − γ for any h; a
vertical wheel (γ = 0, σ v = −ρ ω) gives eq. (1) with α = 90° plus
:mod:`wheelcal.model.rolling`'s Δa term by term (σ v̇ = −ρ ω̇, σ v ψ̇ = −ρ ω ψ̇).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.simulate.field_motion import MotionState
from wheelcal.simulate.field_wheel import WheelGeometry

UP = np.array([0.0, 0.0, 1.0])


def bench_axes(
    theta_rad: np.ndarray,
    heading_rad: np.ndarray,
    wheel: WheelGeometry,
    camber_rad: np.ndarray | None = None,
) -> np.ndarray:
    """A = [X Y Z] (N, 3, 3): the bench axes as world vectors (columns).

    ``camber_rad``: γ per sample (a wheel that leans, :class:`Lean`); default the wheel's.
    """
    theta = np.asarray(theta_rad, dtype=float)[:, None]
    heading = np.asarray(heading_rad, dtype=float)
    forward, left = _forward_left(heading)
    gamma, side = wheel.camber_rad, wheel.side
    if camber_rad is not None:
        gamma = np.asarray(camber_rad, dtype=float)[:, None]
    axle = side * np.cos(gamma) * left + np.sin(gamma) * UP
    up_in_plane = np.cos(gamma) * UP - side * np.sin(gamma) * left
    across = side * forward  # w = Z × u
    axes = np.empty((theta.shape[0], 3, 3))
    axes[:, :, 0] = np.cos(theta) * up_in_plane - np.sin(theta) * across
    axes[:, :, 1] = np.sin(theta) * up_in_plane + np.cos(theta) * across
    axes[:, :, 2] = axle
    return axes


def _forward_left(heading: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    c, s = np.cos(heading), np.sin(heading)
    zero = np.zeros_like(c)
    return np.column_stack([c, s, zero]), np.column_stack([-s, c, zero])


def _to_bench(axes: np.ndarray, world: np.ndarray) -> np.ndarray:
    """Aᵀ x for world vectors x (N, 3)."""
    return np.einsum("nji,nj->ni", axes, world)


@dataclass(frozen=True, eq=False)
class WheelKinematics:
    """World-frame motion of the wheel and the sensor at the sample times (each (N, 3)).

    ``axes`` (N, 3, 3) is A (bench → world).  ``rate_radps`` Ω and
    ``rate_dot_radps2`` Ω̇ are the wheel's angular velocity and acceleration;
    ``hub_*`` the hub's velocity and acceleration; ``lever_m`` q = A p the
    sensor relative to the hub; ``sensor_*`` its velocity and acceleration.
    """

    axes: np.ndarray
    rate_radps: np.ndarray
    rate_dot_radps2: np.ndarray
    hub_velocity_mps: np.ndarray
    hub_accel_mps2: np.ndarray
    lever_m: np.ndarray
    sensor_velocity_mps: np.ndarray
    sensor_accel_mps2: np.ndarray

    def specific_force_bench(self, gravity_mps2: float) -> np.ndarray:
        """The specific force a = Aᵀ (P̈ + g e_z), bench frame (N, 3), m/s²."""
        return _to_bench(self.axes, self.sensor_accel_mps2 + gravity_mps2 * UP)

    def rate_bench(self) -> np.ndarray:
        """Aᵀ Ω, the body rate in the bench frame (N, 3), rad/s."""
        return _to_bench(self.axes, self.rate_radps)

    def to_bench(self, world: np.ndarray) -> np.ndarray:
        """World vectors (N, 3) in the bench frame."""
        return _to_bench(self.axes, world)


@dataclass(frozen=True, eq=False)
class Lean:
    """A camber that changes during the drive: γ(t), γ̇, γ̈ per sample (rad, rad/s, rad/s²).

    The carrier rolls about the direction of travel through the hub (a car's body
    roll, a bicycle's lean), at γ̇ σ f (dZ/dγ = u, and σ f × Z = u); the hub's path
    is unchanged.  Out of the estimator's scope: it refuses such a drive by name.
    """

    camber_rad: np.ndarray
    rate_radps: np.ndarray
    accel_radps2: np.ndarray


def wheel_kinematics(
    state: MotionState,
    wheel: WheelGeometry,
    lean: Lean | None = None,
    shake_radps: np.ndarray | None = None,
    rate_hz: float | None = None,
) -> WheelKinematics:
    """Evaluate the module docstring's world-frame formulas at the states' samples.

    With ``lean`` the carrier turns at Ω_c = ψ̇ e_z + γ̇ σ f, so Ω = Ω_c − ω Z,
    Ż = Ω_c × Z and Ω̇ = ψ̈ e_z + γ̈ σ f + γ̇ σ ψ̇ l − ω̇ Z − ω Ż (ḟ = ψ̇ l).
    ``shake_radps`` (N, 3): the carrier's angular vibration ν about (the vertical, the
    direction of travel σ f, the axle Z), added to Ω_c and, differenced at ``rate_hz``,
    to Ω̇_c (:mod:`~wheelcal.simulate.road_profile`; its attitude is not integrated).
    """
    camber = None if lean is None else lean.camber_rad
    axes = bench_axes(state.theta_rad, state.heading_rad, wheel, camber)
    axle = axes[:, :, 2]
    yaw_rate = state.yaw_rate_radps[:, None]
    omega = state.omega_radps[:, None]
    forward, left = _forward_left(state.heading_rad)
    carrier = yaw_rate * UP  # Ω_c
    carrier_dot = state.yaw_accel_radps2[:, None] * UP
    if lean is not None:
        travel = wheel.side * forward  # σ f
        carrier = carrier + lean.rate_radps[:, None] * travel
        carrier_dot = carrier_dot + lean.accel_radps2[:, None] * travel
        carrier_dot = carrier_dot + (lean.rate_radps[:, None] * yaw_rate) * wheel.side * left
    if shake_radps is not None:
        nu = np.asarray(shake_radps, dtype=float)
        travel = wheel.side * forward
        shaking = nu[:, :1] * UP + nu[:, 1:2] * travel + nu[:, 2:3] * axle
        carrier = carrier + shaking
        carrier_dot = carrier_dot + np.gradient(shaking, 1.0 / float(rate_hz), axis=0)
    rate = carrier - omega * axle  # Ω = Ω_c − ω Z
    axle_dot = np.cross(carrier, axle)  # Ż = Ω_c × Z
    rate_dot = carrier_dot - state.omega_dot_radps2[:, None] * axle - omega * axle_dot
    speed = state.speed_mps[:, None]
    hub_velocity = speed * forward
    hub_accel = state.speed_dot_mps2[:, None] * forward + speed * yaw_rate * left
    lever = axes @ wheel.lever_m
    sensor_velocity = hub_velocity + np.cross(rate, lever)
    sensor_accel = hub_accel + np.cross(rate_dot, lever) + np.cross(rate, np.cross(rate, lever))
    return WheelKinematics(
        axes=axes,
        rate_radps=rate,
        rate_dot_radps2=rate_dot,
        hub_velocity_mps=hub_velocity,
        hub_accel_mps2=hub_accel,
        lever_m=lever,
        sensor_velocity_mps=sensor_velocity,
        sensor_accel_mps2=sensor_accel,
    )
