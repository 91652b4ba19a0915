"""An oracle for the physics of the wheel, written without wheelcal's model code.

Nothing here imports ``wheelcal.model`` (forward model, kinematics, bench force,
effects): the oracle places the sensor in a world frame, moves it, and
differentiates its *position* numerically.  Tests compare it with the model's
prediction and the simulator's output; a sign or factor error in eq. (1) that the
model, the simulator and the truth-based CRLB would share shows up here.

Conventions (CONTRACT.md "Physical conventions", README "Conventions"), and how
each enters the oracle:

* World frame: "up" is +z; gravity is g⃗ = −g·up.  The accelerometer senses the
  specific force f = p̈ − g⃗ (at rest on a table it reads +g along up).
* Bench frame, fixed to the wheel: Z along the wheel axis on the side that points
  upward, tilted by α ∈ [0°, 90°] from up (toward an arbitrary horizontal
  heading, a free choice: the physics may not depend on it).  X is radial from
  the sensor toward the axle, so the sensor sits at p = −r X.  Y = Z × X (a
  right-handed frame) is the direction of increasing wheel angle ϑ, i.e.
  dp/dϑ ∥ +Y; with p = −r X this means dX/dϑ = −Y, so the frame turns about
  −Z: X(ϑ) = cosϑ X₀ − sinϑ Y₀, Y(ϑ) = sinϑ X₀ + cosϑ Y₀ with Y₀ = Z × X₀.
* Origin of ϑ: eq. (1) has a_X = … + g sinα cosϑ, so at ϑ = 0 the axis X
  points up the wheel plane as far as it can (X₀ = the in-plane component of
  up, normalised): the sensor is at the bottom of the wheel.  This fixes only
  the origin; the *sign* of the g sinα sinϑ term then follows from the
  direction of rotation above, and the signs of r ω², r ω̇ from p = −r X.
* ω = dϑ/dt is signed; the oracle never uses ω or ω̇: it differentiates the
  position p(t) = −r X(ϑ(t)) in time (central differences), so the centripetal
  and tangential terms come out of the numbers, not out of a formula.
* The sensor: s = R a with a = (f·X, f·Y, f·Z) and R bench → sensor (a proper
  rotation; Euler angles ZYX intrinsic, R = Rz(e₁) Ry(e₂) Rx(e₃));
  v = o + Γ s with Γ = diag(gain).  Effects with one-line physics are applied on
  top (see :func:`sensor_output`).
* The gyro on the wheel measures the body rate: the frame's angular velocity in
  its own axes, obtained from the finite rotation Bᵀ(t−h) B(t+h) of the bench
  axes B = [X Y Z] over 2h, expressed in the sensor axes with R.

The spin polynomial of eq. (2), ϑ(t) = ϑ₀ + Σ ω_k t^(k+1)/(k+1) (centred t),
is evaluated here from the coefficients directly (:func:`polynomial_theta`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation as SciRotation

#: Step of the central differences in time (s).  With the 4th-order stencil the
#: truncation error is ~h⁴ r ω⁶/90 (≈ 4e-8 m/s² at r = 0.28 m, ω = 15 rad/s) and
#: the round-off ~ε r ϑ / h² (≈ 1e-8 m/s² after 300 rad of spin): ~1e-9 of the signal.
STEP_S = 1e-3


def polynomial_theta(theta0_rad: float, omega_coefficients) -> Callable[[np.ndarray], np.ndarray]:
    """ϑ(t) of eq. (2) from (ϑ₀, ω₀, …, ω_K), straight from the definition."""
    coeffs = np.asarray(omega_coefficients, dtype=float)
    integral = np.concatenate([[theta0_rad], coeffs / np.arange(1, coeffs.size + 1)])
    return lambda t: np.polynomial.polynomial.polyval(np.asarray(t, dtype=float), integral)


def euler_zyx_matrix(euler_deg) -> np.ndarray:
    """R = Rz(e₁) Ry(e₂) Rx(e₃) (intrinsic ZYX) by scipy, not by wheelcal."""
    return SciRotation.from_euler("ZYX", euler_deg, degrees=True).as_matrix()


def bench_axes(theta_rad: np.ndarray, tilt_rad: float, heading_rad: float = 0.7) -> np.ndarray:
    """Bench axes as world vectors, shape (N, 3, 3): [..., :, 0] = X, 1 = Y, 2 = Z."""
    up = np.array([0.0, 0.0, 1.0])
    horizontal = np.array([np.cos(heading_rad), np.sin(heading_rad), 0.0])
    z_axis = np.cos(tilt_rad) * up + np.sin(tilt_rad) * horizontal
    # The in-plane direction of up, (up − (up·Z) Z)/sinα, written so α = 0 works too.
    x0 = np.sin(tilt_rad) * up - np.cos(tilt_rad) * horizontal
    y0 = np.cross(z_axis, x0)
    th = np.asarray(theta_rad, dtype=float)[:, None]
    x_axis = np.cos(th) * x0 - np.sin(th) * y0  # dX/dϑ = −Y
    y_axis = np.sin(th) * x0 + np.cos(th) * y0
    out = np.empty((th.shape[0], 3, 3))
    out[:, :, 0] = x_axis
    out[:, :, 1] = y_axis
    out[:, :, 2] = z_axis
    return out


def specific_force_bench(
    theta_of_t: Callable[[np.ndarray], np.ndarray],
    t_s: np.ndarray,
    tilt_rad: float,
    radius_m: float,
    gravity_mps2: float,
    heading_rad: float = 0.7,
    step_s: float = STEP_S,
) -> np.ndarray:
    """a(t) = f in bench axes (N, 3), from p(t) = −r X(ϑ(t)) differentiated numerically.

    p̈ by the 4th-order central stencil (−p₋₂ + 16p₋₁ − 30p₀ + 16p₁ − p₂)/(12h²).
    """
    t = np.asarray(t_s, dtype=float)
    weights = np.array([-1.0, 16.0, -30.0, 16.0, -1.0]) / (12 * step_s**2)
    accel_world = np.zeros((t.size, 3))
    for k, w in zip(range(-2, 3), weights, strict=True):
        axes = bench_axes(theta_of_t(t + k * step_s), tilt_rad, heading_rad)
        accel_world += w * (-radius_m * axes[:, :, 0])
    up = np.array([0.0, 0.0, 1.0])
    force_world = accel_world + gravity_mps2 * up  # f = p̈ − g⃗, g⃗ = −g·up
    axes = bench_axes(theta_of_t(t), tilt_rad, heading_rad)
    return np.einsum("nwj,nw->nj", axes, force_world)  # a_j = f · (axis j)


def body_rate_bench(
    theta_of_t: Callable[[np.ndarray], np.ndarray],
    t_s: np.ndarray,
    tilt_rad: float,
    heading_rad: float = 0.7,
    step_s: float = 1e-5,
) -> np.ndarray:
    """Angular velocity of the bench frame in its own axes (N, 3), by finite rotations."""
    t = np.asarray(t_s, dtype=float)
    before = bench_axes(theta_of_t(t - step_s), tilt_rad, heading_rad)
    after = bench_axes(theta_of_t(t + step_s), tilt_rad, heading_rad)
    relative = np.einsum("nwi,nwj->nij", before, after)  # Bᵀ(t−h) B(t+h)
    return SciRotation.from_matrix(relative).as_rotvec() / (2 * step_s)


def sensor_output(
    bench_force_mps2: np.ndarray,
    rotation: np.ndarray,
    gain: np.ndarray,
    offset_mps2: np.ndarray,
    t_s: np.ndarray | None = None,
    *,
    nonlinearity_per_mps2=(0.0, 0.0, 0.0),
    cross_axis_rad=(0.0, 0.0, 0.0),
    offset_drift_mps2_per_s=(0.0, 0.0, 0.0),
    gain_drift_per_s=(0.0, 0.0, 0.0),
    warmup_mps2=(0.0, 0.0, 0.0),
    warmup_tau_s: float = 1.0,
) -> np.ndarray:
    """v (N, 3) of a sensor with these errors, each a line of physics.

    * mounting: s = R a (R bench → sensor);
    * non-orthogonal axes: axis y leans toward x by l_yx, z toward x and y by
      l_zx, l_zy: s' = (I + L) s with L strictly lower triangular;
    * per-axis quadratic response: s''_i = s'_i + k_i s'_i²;
    * gain that drifts linearly about the centre: γ_i(t) = γ_i (1 + h_i t);
    * offset with a linear drift and a warm-up (both zero at t = 0):
      o_i(t) = o_i + d_i t + a_i (1 − e^(−t/τ));
    * v_i = o_i(t) + γ_i(t) s''_i.
    """
    s = np.asarray(bench_force_mps2, dtype=float) @ np.asarray(rotation).T
    lower = np.zeros((3, 3))
    lower[1, 0], lower[2, 0], lower[2, 1] = cross_axis_rad
    s = s @ (np.eye(3) + lower).T
    s = s + np.asarray(nonlinearity_per_mps2) * s**2
    t = np.zeros(s.shape[0]) if t_s is None else np.asarray(t_s, dtype=float)
    gain_t = np.asarray(gain) * (1 + np.outer(t, gain_drift_per_s))
    offset_t = (
        np.asarray(offset_mps2)
        + np.outer(t, offset_drift_mps2_per_s)
        + np.outer(1 - np.exp(-t / warmup_tau_s), warmup_mps2)
    )
    return offset_t + gain_t * s


def torqued_theta(
    theta0_rad: float,
    omega_coefficients,
    sin_radps2: float,
    cos_radps2: float,
    t_start_s: float,
    t_end_s: float,
) -> Callable[[np.ndarray], np.ndarray]:
    """ϑ(t) of a wheel whose base spin-down (eq. 2) is disturbed by a once-per-turn torque.

    Newton for a rigid wheel: ϑ̈ = ω̇_base(t) + a sinϑ + b cosϑ (an off-centre mass
    in gravity gives such a torque).  Integrated by scipy from ``t_start_s``,
    starting on the steady forced response of a free rotor turning at ω:
    Δϑ = −(a sinϑ + b cosϑ)/ω², Δω = −(a cosϑ − b sinϑ)/ω (differentiate the first
    to get the second; its second derivative is the torque), so no spurious
    constant change of speed is put in at the start.
    """
    from scipy.integrate import solve_ivp

    base = polynomial_theta(theta0_rad, omega_coefficients)
    coeffs = np.asarray(omega_coefficients, dtype=float)
    dot = coeffs[1:] * np.arange(1, coeffs.size)  # ω̇_base(t) polynomial

    def rhs(t, y):
        torque = sin_radps2 * np.sin(y[0]) + cos_radps2 * np.cos(y[0])
        return [y[1], np.polynomial.polynomial.polyval(t, dot) + torque]

    th = float(base(np.array([t_start_s]))[0])
    w = float(np.polynomial.polynomial.polyval(t_start_s, coeffs))
    u = sin_radps2 * np.sin(th) + cos_radps2 * np.cos(th)
    du = sin_radps2 * np.cos(th) - cos_radps2 * np.sin(th)
    y0 = [th - u / w**2, w - du / w]
    sol = solve_ivp(
        rhs, (t_start_s, t_end_s), y0, method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True
    )
    return lambda t: sol.sol(np.asarray(t, dtype=float))[0]
