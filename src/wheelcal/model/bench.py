"""Specific force in the bench frame, eq. (1), and its partial derivatives.

Bench frame (CONTRACT): Z along the wheel axis on the upward side (tilt α
between Z and the vertical, α ∈ [0°, 90°]), X radial from the sensor toward the
axis, Y = Z × X the direction of increasing ϑ.  With the sensor at p = −r X
and dX/dϑ = −Y, p̈ = r ω̇ Y + r ω² X; adding the reaction to gravity gives

    a_X = r ω² + g sin α cos ϑ
    a_Y = r ω̇  + g sin α sin ϑ                                       (1)
    a_Z = g cos α
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model.kinematics import Kinematics


@dataclass(frozen=True, eq=False)
class BenchForce:
    """a(t) of eq. (1), shape (N, 3), and the partials the Jacobian needs."""

    accel_mps2: np.ndarray
    sin_theta: np.ndarray
    cos_theta: np.ndarray
    g_sin_tilt: float
    g_cos_tilt: float


def bench_force(
    kin: Kinematics, tilt_rad: float, radius_m: float, gravity_mps2: float
) -> BenchForce:
    """Evaluate eq. (1)."""
    s, c = np.sin(kin.theta_rad), np.cos(kin.theta_rad)
    g_sin = gravity_mps2 * np.sin(tilt_rad)
    g_cos = gravity_mps2 * np.cos(tilt_rad)
    a = np.empty((kin.theta_rad.size, 3))
    a[:, 0] = radius_m * kin.omega_radps**2 + g_sin * c
    a[:, 1] = radius_m * kin.omega_dot_radps2 + g_sin * s
    a[:, 2] = g_cos
    return BenchForce(a, s, c, g_sin, g_cos)


def d_force_d_tilt(force: BenchForce) -> np.ndarray:
    """∂a/∂α, shape (N, 3)."""
    out = np.empty_like(force.accel_mps2)
    out[:, 0] = force.g_cos_tilt * force.cos_theta
    out[:, 1] = force.g_cos_tilt * force.sin_theta
    out[:, 2] = -force.g_sin_tilt
    return out


def d_force_d_radius(kin: Kinematics) -> np.ndarray:
    """∂a/∂r, shape (N, 3)."""
    out = np.zeros((kin.theta_rad.size, 3))
    out[:, 0] = kin.omega_radps**2
    out[:, 1] = kin.omega_dot_radps2
    return out


def d_force_d_gravity(force: BenchForce, tilt_rad: float) -> np.ndarray:
    """∂a/∂g, shape (N, 3) — used only by the systematic budget."""
    out = np.empty_like(force.accel_mps2)
    out[:, 0] = np.sin(tilt_rad) * force.cos_theta
    out[:, 1] = np.sin(tilt_rad) * force.sin_theta
    out[:, 2] = np.cos(tilt_rad)
    return out
