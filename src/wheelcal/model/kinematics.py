"""Wheel kinematics: phase ϑ(t), rate ω(t) = dϑ/dt and ω̇(t) of eq. (2).

The spin is a polynomial about the window centre; its derivatives with respect
to the coefficient vector p = (ϑ₀, ω₀, …, ω_K) are exact and cheap:

    ∂ϑ/∂ϑ₀ = 1,  ∂ϑ/∂ω_k = t^(k+1)/(k+1),  ∂ω/∂ω_k = t^k,  ∂ω̇/∂ω_k = k t^(k−1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model.parameters import SpinParams


@dataclass(frozen=True, eq=False)
class Kinematics:
    """ϑ, ω, ω̇ at each sample time, optionally with derivatives w.r.t. p.

    The ``d_*`` arrays have shape (K + 2, N), rows (ϑ₀, ω₀, …, ω_K).
    """

    theta_rad: np.ndarray
    omega_radps: np.ndarray
    omega_dot_radps2: np.ndarray
    d_theta: np.ndarray | None = None
    d_omega: np.ndarray | None = None
    d_omega_dot: np.ndarray | None = None
    #: (3, N): ∂(ϑ, ω, ω̇)/∂α where a tilt-aware spin effect makes them depend on the tilt.
    d_tilt: np.ndarray | None = None


def spin_kinematics(spin: SpinParams, t_s: np.ndarray, derivatives: bool = False) -> Kinematics:
    """Evaluate eq. (2) at times ``t_s`` (seconds from the window centre)."""
    t = np.asarray(t_s, dtype=float)
    degree = spin.degree
    powers = _powers(t, degree)
    k = np.arange(degree + 1)
    omega_coef = spin.omega_radps
    # Eq. (2): ϑ = ϑ₀ + Σ ω_k t^(k+1)/(k+1), ω = Σ ω_k t^k, ω̇ = Σ k ω_k t^(k−1).
    theta = spin.theta0_rad + (omega_coef / (k + 1)) @ powers[1:]
    omega = omega_coef @ powers[:-1]
    omega_dot = (omega_coef[1:] * k[1:]) @ powers[:-2] if degree >= 1 else np.zeros_like(t)
    if not derivatives:
        return Kinematics(theta, omega, omega_dot)
    return Kinematics(theta, omega, omega_dot, *_partials(powers, degree))


def spin_partials(spin: SpinParams, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(∂ϑ/∂p, ∂ω/∂p, ∂ω̇/∂p), each (K + 2, N): the rows :func:`spin_kinematics` adds.

    For a caller that has ϑ, ω, ω̇ at these times already (the same numbers).
    """
    return _partials(_powers(np.asarray(t_s, dtype=float), spin.degree), spin.degree)


def _powers(t: np.ndarray, degree: int) -> np.ndarray:
    """t^0 … t^(K+1), (K + 2, N), by products (pow is slow)."""
    powers = np.empty((degree + 2, t.size))
    powers[0] = 1.0
    for k in range(1, degree + 2):
        powers[k] = powers[k - 1] * t
    return powers


def _partials(powers: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    k = np.arange(degree + 1)
    d_theta = np.empty(powers.shape)
    d_theta[0] = 1.0
    d_theta[1:] = powers[1:] / (k + 1)[:, None]
    d_omega = np.zeros(powers.shape)
    d_omega[1:] = powers[:-1]
    d_omega_dot = np.zeros(powers.shape)
    if degree >= 1:
        d_omega_dot[2:] = powers[:degree] * k[1:, None]
    return d_theta, d_omega, d_omega_dot
