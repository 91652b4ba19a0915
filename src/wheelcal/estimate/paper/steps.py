"""The four steps of Pedersini's calibration (Sec. III-A to III-D), one function each.

Every search is a Nelder–Mead simplex ([17] in the paper, through
:func:`scipy.optimize.minimize`); the small helper :func:`nelder_mead` fixes the
initial simplex (explicit steps, because scipy's default of 5 % of each
coordinate is meaningless for angles and phases) and records the number of
objective evaluations.

Data flow (r = T v, eq. 15)::

    v ──A──▶ T = T''T'            (eq. 24, 26)
    r_y ─B─▶ ϑ₀, ω₀…ω_K, A, k     (eq. 29)
    r, ϑ(t), r ─C─▶ R, α, Γ       (eq. 30–34)
    v, R, α, Γ ─D─▶ o             (eq. 35)

Between B and C, :func:`resolve_signs` fixes the discrete choices the text
leaves open (the π-ambiguity of eq. 26, the hemisphere of eq. 24 and the sign
of ϑ, which r_y alone cannot see) so that W = TΓR has a positive diagonal and
R₀ = Tᵀ (eq. 18) is a sensible starting point.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import legendre
from numpy.polynomial import polynomial as poly
from scipy.optimize import minimize
from scipy.signal import hilbert

from wheelcal.model import (
    BenchParams,
    CalibrationParams,
    Rotation,
    SensorParams,
    SpinParams,
    predict,
)

#: Objective value returned for candidates the model cannot represent (non-positive gain).
_INFEASIBLE = 1e30


@dataclass(frozen=True)
class SearchResult:
    """Outcome of one Nelder–Mead search."""

    x: np.ndarray
    fun: float
    evaluations: int
    converged: bool
    message: str


def nelder_mead(
    objective: Callable[[np.ndarray], float],
    x0: np.ndarray,
    steps: np.ndarray,
    max_evaluations: int,
    xatol: float,
    fatol: float,
) -> SearchResult:
    """Minimise ``objective`` by Nelder–Mead from a simplex x0, x0 + steps_i e_i."""
    x0 = np.asarray(x0, dtype=float)
    simplex = np.vstack([x0, x0 + np.diag(np.broadcast_to(steps, x0.shape))])
    res = minimize(
        objective,
        x0,
        method="Nelder-Mead",
        options={
            "initial_simplex": simplex,
            "maxfev": max_evaluations,
            "maxiter": 10 * max_evaluations,
            "xatol": xatol,
            "fatol": fatol,
            "adaptive": x0.size > 4,  # dimension-dependent coefficients (Gao & Han)
        },
    )
    return SearchResult(
        np.asarray(res.x), float(res.fun), int(res.nfev), bool(res.success), res.message
    )


# ---------------------------------------------------------------------------
# Step A: partial re-alignment, eq. (22)–(26)


def first_rotation(eps_x_rad: float, eps_y_rad: float) -> np.ndarray:
    """T'(ε_x, ε_y) = R_Y(ε_y) R_X(ε_x), the rotation about X and Y of eq. (24)."""
    return Rotation.from_euler_deg(0.0, np.rad2deg(eps_y_rad), np.rad2deg(eps_x_rad)).matrix


def second_rotation(eps_z_rad: float) -> np.ndarray:
    """T''(ε_z) = R_Z(ε_z), the rotation about Z of eq. (26)."""
    return Rotation.from_euler_deg(np.rad2deg(eps_z_rad), 0.0, 0.0).matrix


@dataclass(frozen=True, eq=False)
class Realignment:
    """Result of step III-A: T = T''T' and the angles found."""

    matrix: np.ndarray
    eps_x_rad: float
    eps_y_rad: float
    eps_z_rad: float
    evaluations: int
    converged: bool


def realign(
    accel_mps2: np.ndarray, max_evaluations: int, grid_step_deg: float = 15.0
) -> Realignment:
    """Step III-A: T' by eq. (24), then T'' by eq. (26).

    Both searches start from the best point of a coarse grid (the paper gives
    no starting point); grid evaluations are counted with the simplex ones.
    The variance of r'_z = t'₃ v is evaluated as t'₃ C t'₃ᵀ with C the 3×3
    sample covariance of v: the same number as σ²[r'_z(t)], at O(1) cost.
    """
    cov = np.cov(accel_mps2.T)

    def variance_rz(eps: np.ndarray) -> float:  # Eq. (24)
        row = first_rotation(*eps)[2]
        return float(row @ cov @ row)

    # z' ranges over a hemisphere for ε_x, ε_y ∈ [−90°, 90°].
    axis = np.deg2rad(np.arange(-90.0, 90.0 + 1e-9, grid_step_deg))
    grid = [np.array([ex, ey]) for ex in axis for ey in axis]
    start = min(grid, key=variance_rz)
    res1 = nelder_mead(
        variance_rz,
        start,
        np.deg2rad([grid_step_deg / 3] * 2),
        max_evaluations,
        xatol=1e-9,
        fatol=1e-16 * float(np.trace(cov)),
    )
    t1 = first_rotation(*res1.x)
    r1 = accel_mps2 @ t1.T  # Eq. (22)

    def excursion_ry(eps: np.ndarray) -> float:  # Eq. (26); r_y = sinε r'_x + cosε r'_y
        r_y = np.sin(eps[0]) * r1[:, 0] + np.cos(eps[0]) * r1[:, 1]
        return float(r_y.max() - r_y.min())

    # The excursion has period π in ε_z (r_y only flips sign): grid over [0, π).
    z_grid = np.deg2rad(np.arange(0.0, 180.0, grid_step_deg / 3))
    z_start = min(z_grid, key=lambda e: excursion_ry(np.array([e])))
    res2 = nelder_mead(
        excursion_ry,
        np.array([z_start]),
        np.deg2rad([grid_step_deg / 6]),
        max_evaluations,
        xatol=1e-9,
        fatol=1e-12,
    )
    matrix = second_rotation(res2.x[0]) @ t1  # T = T''T'
    return Realignment(
        matrix=matrix,
        eps_x_rad=float(res1.x[0]),
        eps_y_rad=float(res1.x[1]),
        eps_z_rad=float(res2.x[0]),
        evaluations=len(grid) + res1.evaluations + z_grid.size + res2.evaluations,
        converged=res1.converged and res2.converged,
    )


# ---------------------------------------------------------------------------
# Step B: bench rotation, eq. (27)–(29)


@dataclass(frozen=True, eq=False)
class Motion:
    """Result of step III-B: ϑ(t) of eq. (2) and r_y = k + A sin ϑ of eq. (28)."""

    spin: SpinParams
    amplitude_mps2: float  # A
    constant_mps2: float  # k
    evaluations: int
    converged: bool


def _legendre_to_spin(coef: np.ndarray, half_window_s: float) -> SpinParams:
    """ϑ(t) = Σ c_j P_j(t / T_h)  →  (ϑ₀, ω₀…ω_K) of eq. (2)."""
    p = legendre.leg2poly(coef) / half_window_s ** np.arange(coef.size)  # ϑ in powers of t
    k = np.arange(1, coef.size)
    return SpinParams(theta0_rad=p[0], omega_radps=p[1:] * k)  # ω_{k−1} = k p_k


def initial_phase(t_s: np.ndarray, r_y: np.ndarray, degree: int) -> np.ndarray:
    """Phase polynomial (Legendre coefficients in t/T_h) from the analytic signal of r_y.

    The paper does not say how eq. (29) is initialised.  Here: remove a slow
    trend, take the unwrapped phase φ(t) of the analytic signal (Hilbert
    transform) — for A sin ϑ it is ϑ − π/2 — and fit it with a polynomial of
    degree K + 1 on the central 90 % of the window (the FFT-based transform is
    distorted near the ends).
    """
    half = 0.5 * (t_s[-1] - t_s[0])
    x = t_s / half
    trend = poly.polyval(x, poly.polyfit(x, r_y, 2))
    phase = np.unwrap(np.angle(hilbert(r_y - trend))) + 0.5 * np.pi
    keep = np.abs(x) <= 0.9
    return legendre.legfit(x[keep], phase[keep], degree + 1)


def fit_motion(t_s: np.ndarray, r_y: np.ndarray, degree: int, max_evaluations: int) -> Motion:
    """Step III-B: eq. (29) by Nelder–Mead in K + 4 dimensions.

    The phase is searched as Legendre coefficients c_j of ϑ in x = t/T_h
    (T_h = half window), which is the same polynomial space as eq. (2) but with
    nearly uncorrelated coordinates; c_j is scaled by A/√(2j+1) and k by √2 so
    that the Hessian of the mean squared residual is ≈ identity.  The result
    is mapped back to (ϑ₀, ω₀…ω_K) exactly.
    """
    half = 0.5 * (t_s[-1] - t_s[0])
    basis = legendre.legvander(t_s / half, degree + 1)  # (N, K+2)
    c0 = initial_phase(t_s, r_y, degree)
    k0 = float(np.mean(r_y))
    a0 = float(np.sqrt(2.0) * np.std(r_y))  # σ[r_y] = A/√2, eq. (31)
    phase_scale = a0 / np.sqrt(2 * np.arange(degree + 2) + 1)

    def unpack(u: np.ndarray) -> tuple[np.ndarray, float, float]:
        return u[: degree + 2] / phase_scale, u[degree + 2], u[degree + 3] / np.sqrt(2.0)

    def misfit(u: np.ndarray) -> float:  # Eq. (29), divided by N
        coef, amp, const = unpack(u)
        res = r_y - (const + amp * np.sin(basis @ coef))
        return float(res @ res) / r_y.size

    u0 = np.concatenate([c0 * phase_scale, [a0, k0 * np.sqrt(2.0)]])
    first = misfit(u0)
    res = nelder_mead(
        misfit,
        u0,
        np.full(u0.size, 0.02 * a0),
        max_evaluations,
        xatol=1e-6 * a0,
        fatol=1e-12 * first,
    )
    coef, amp, const = unpack(res.x)
    return Motion(
        spin=_legendre_to_spin(coef, half),
        amplitude_mps2=float(amp),
        constant_mps2=float(const),
        evaluations=res.evaluations + 1,
        converged=res.converged,
    )


# ---------------------------------------------------------------------------
# Between B and C: the discrete choices the text leaves open


@dataclass(frozen=True, eq=False)
class SignChoice:
    """T and ϑ(t) made consistent with a right-handed bench frame, X toward the axis."""

    realignment: np.ndarray
    motion: Motion
    sin_tilt_guess: float


def resolve_signs(
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    realignment: np.ndarray,
    motion: Motion,
    radius_m: float,
    gravity_mps2: float,
) -> SignChoice:
    """Fix the discrete ambiguities of steps A and B.

    * Eq. (26) is minimised at ε_z and ε_z + π, eq. (24) on either hemisphere.
      T ← D T with D = diag(d₁, d₂, d₃), det D = 1, keeps T a rotation and
      W = TΓR upper triangular, and makes its diagonal positive: d₁ is the
      sign of the centripetal term r ω² in r_x (a_X of eq. 1 points toward
      the axis), d₃ the sign of mean(r_z) (Z up when |o| ≪ g cos α; the other
      choice is the discrete twin, resolved later by the smaller offset).
    * r_y = k + A sin ϑ cannot tell ϑ from −ϑ or ϑ + π.  After the flip, A > 0
      and the cos ϑ term of r_x (w₁₁ g sinα cosϑ, w₁₁ > 0) fix ϑ ← ±ϑ̂ (+π).

    The same regression of r_x on (1, ω², cos ϑ̂, sin ϑ̂, ω̇) gives a
    gain-free first guess of the tilt, sin α = r |β_cos| / (g |β_ω²|).
    """
    kin_omega = motion.spin.omega_at(t_s)
    omega_dot = poly.polyval(t_s, poly.polyder(motion.spin.omega_radps))
    theta_hat = motion.spin.theta_at(t_s)
    r = accel_mps2 @ realignment.T
    design = np.column_stack(
        [np.ones_like(t_s), kin_omega**2, np.cos(theta_hat), np.sin(theta_hat), omega_dot]
    )
    beta = np.linalg.lstsq(design, r[:, 0], rcond=None)[0]
    d1 = 1.0 if beta[1] > 0 else -1.0
    d3 = 1.0 if np.mean(r[:, 2]) > 0 else -1.0
    d2 = d1 * d3
    flipped = np.diag([d1, d2, d3]) @ realignment
    amp = d2 * motion.amplitude_mps2
    s_sin = 1.0 if amp > 0 else -1.0
    s_cos = 1.0 if d1 * beta[2] > 0 else -1.0
    # ϑ = σ ϑ̂ + φ with σ = s_sin s_cos, φ = 0 or π (see the docstring).
    direction = s_sin * s_cos
    spin = SpinParams(
        theta0_rad=direction * motion.spin.theta0_rad + (0.0 if s_cos > 0 else np.pi),
        omega_radps=direction * motion.spin.omega_radps,
    )
    sin_tilt = radius_m * abs(beta[2]) / (gravity_mps2 * abs(beta[1]))
    return SignChoice(
        realignment=flipped,
        motion=Motion(
            spin=spin,
            amplitude_mps2=abs(amp),
            constant_mps2=d2 * motion.constant_mps2,
            evaluations=motion.evaluations,
            converged=motion.converged,
        ),
        sin_tilt_guess=float(np.clip(sin_tilt, 0.02, 0.999)),
    )


# ---------------------------------------------------------------------------
# Step C: misalignment, tilt and gain, eq. (30)–(34)


def gain_system(realignment: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Coefficient matrix U of eq. (30): rows w₂₁, w₃₁, w₃₂, w₂₂ as linear in γ."""
    t, r = realignment, rotation
    # w_ij = Σ_k t_ik γ_k r_kj
    return np.array([t[i] * r[:, j] for i, j in ((1, 0), (2, 0), (2, 1), (1, 1))])


def gains_from_system(realignment: np.ndarray, rotation: np.ndarray, w22: float) -> np.ndarray:
    """γ = (UᵀU)⁻¹Uᵀb, eq. (32) (the printed eq. omits the transpose on U)."""
    u = gain_system(realignment, rotation)
    b = np.array([0.0, 0.0, 0.0, w22])
    return np.linalg.solve(u.T @ u, u.T @ b)


@dataclass(frozen=True, eq=False)
class Geometry:
    """Result of step III-C."""

    rotation: Rotation
    tilt_rad: float
    gain: np.ndarray
    system_residual: float  # ‖Uγ − b‖ / w̄₂₂ of eq. (30) at the optimum
    evaluations: int
    converged: bool


def fit_geometry(
    t_s: np.ndarray,
    accel_mps2: np.ndarray,
    realignment: np.ndarray,
    motion: Motion,
    sin_tilt_guess: float,
    radius_m: float,
    gravity_mps2: float,
    max_evaluations: int,
) -> Geometry:
    """Step III-C: ⟨R, α⟩ of eq. (34) by a 4-D Nelder–Mead, Γ from eq. (32).

    The search variables are three Euler angles (deg, :data:`EULER_CONVENTION`)
    of the correction R₀ᵀR, with R₀ = Tᵀ (eq. 18), and α (deg) starting from
    ``sin_tilt_guess``.  Measuring the angles from R₀ rather than from the
    bench frame is the same 3-D search but keeps it away from the Euler
    singularity whatever the mounting.  For each candidate, w̄₂₂ = A/(g sinα)
    (eq. 31, with A from step B) and the model is the full eq. (1), r ω̇
    included, evaluated by :func:`wheelcal.model.predict`.
    """
    r0 = accel_mps2 @ realignment.T
    r0 = r0 - r0.mean(axis=0)  # Eq. (33)
    base = realignment.T  # Eq. (18): R₀ = Tᵀ

    def candidate(x: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
        rot = base @ Rotation.from_euler_deg(*x[:3]).matrix
        tilt = np.deg2rad(x[3])
        w22 = motion.amplitude_mps2 / (gravity_mps2 * np.sin(tilt))  # Eq. (31)
        return rot, tilt, gains_from_system(realignment, rot, w22)

    def misfit(x: np.ndarray) -> float:
        rot, tilt, gain = candidate(x)
        if not np.all(gain > 0) or not 0 < tilt < np.pi:
            return _INFEASIBLE
        params = CalibrationParams(
            spin=motion.spin,
            bench=BenchParams(tilt_rad=tilt, radius_m=radius_m, misalignment=Rotation(rot)),
            sensor=SensorParams(offset_mps2=np.zeros(3), gain=gain),  # o is irrelevant here
            gravity_mps2=gravity_mps2,
        )
        rm = predict(params, t_s) @ realignment.T  # r^m = T v^m
        res = r0 - (rm - rm.mean(axis=0))  # Eq. (33)–(34)
        return float(np.sum(res * res)) / t_s.size

    x0 = np.array([0.0, 0.0, 0.0, np.rad2deg(np.arcsin(sin_tilt_guess))])
    res = nelder_mead(misfit, x0, np.full(4, 0.5), max_evaluations, xatol=1e-5, fatol=1e-14)
    rot, tilt, gain = candidate(res.x)
    w22 = motion.amplitude_mps2 / (gravity_mps2 * np.sin(tilt))
    u = gain_system(realignment, rot)
    system_residual = float(np.linalg.norm(u @ gain - [0.0, 0.0, 0.0, w22]) / abs(w22))
    return Geometry(
        rotation=Rotation(rot),
        tilt_rad=float(tilt),
        gain=gain,
        system_residual=system_residual,
        evaluations=res.evaluations,
        converged=res.converged,
    )


# ---------------------------------------------------------------------------
# Step D: offset, eq. (35)


@dataclass(frozen=True, eq=False)
class Offset:
    """Result of step III-D."""

    offset_mps2: np.ndarray
    evaluations: int
    converged: bool


def fit_offset(
    t_s: np.ndarray, accel_mps2: np.ndarray, params: CalibrationParams, max_evaluations: int
) -> Offset:
    """Step III-D: o = argmin ‖v − v^m‖² (eq. 35), Nelder–Mead from the mean residual."""
    no_offset = params.with_changes(
        sensor=SensorParams(offset_mps2=np.zeros(3), gain=params.sensor.gain)
    )
    base = accel_mps2 - predict(no_offset, t_s)  # v − ΓRa; v^m = o + ΓRa (eq. 6)

    def misfit(o: np.ndarray) -> float:  # Eq. (35), divided by N
        res = base - o
        return float(np.sum(res * res)) / t_s.size

    res = nelder_mead(
        misfit, base.mean(axis=0), np.full(3, 0.01), max_evaluations, xatol=1e-7, fatol=1e-15
    )
    return Offset(offset_mps2=res.x, evaluations=res.evaluations, converged=res.converged)
