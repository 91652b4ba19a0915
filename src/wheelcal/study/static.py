"""The six-pose static calibration users would pick instead of the wheel.

The sensor of eq. (5), v = o + Γ s, is held still in P poses (six: each axis
up, then down); at rest it senses only gravity, s_i = g u_i with u_i a unit
vector, so the pose means m_i satisfy

    ‖Γ⁻¹ (m_i − o)‖ = g                                             (S1)

whatever the (unknown, imperfect) pose.  The standard fits:

* **ellipsoid** — (S1) squared is an axis-aligned ellipsoid,
  Σ_k A_k m_k² + B_k m_k + C = 0, linear in (A, B, C) up to scale: the
  smallest right singular vector, then o_k = −B_k / 2A_k and
  (γ_k g)² = (Σ_j B_j²/4A_j − C) / A_k;
* **|a| = g least squares** — minimise Σ_i (‖Γ⁻¹(m_i − o)‖ − g)² by
  Gauss–Newton from the ellipsoid.  With exactly six poses both fit (S1)
  exactly and agree; with more poses the second is the ML estimate.

The pose means are sufficient statistics: within a pose the model is a
constant.  The bound on (o, γ) treats each pose's direction u_i as two
nuisance parameters (the poses are not known), so pose i informs only along
the normal of the ellipsoid, and F = Σ_i Schur complement of the nuisance
block in J_iᵀ Σ_i⁻¹ J_i, with J_i = ∂m_i/∂(o, γ, u_i) and Σ_i the covariance of
a pose mean (σ²/n for white noise; the long-run variance for AR noise).

Time budget: the poses share the wheel's total recording time T; each pose
loses ``settle_s`` to turning the sensor and waiting for it to be still, and
keeps T/P − settle_s of samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.model import GAIN_NAMES, OFFSET_NAMES, STANDARD_GRAVITY_MPS2, SensorParams, exp_so3
from wheelcal.simulate import NoiseSpec

#: Names of the static method's parameters (a subset of the wheel's).
STATIC_NAMES = (*OFFSET_NAMES, *GAIN_NAMES)


@dataclass(frozen=True)
class StaticPlan:
    """Sampling plan of a static calibration: P poses sharing ``total_s`` seconds."""

    total_s: float
    rate_hz: float
    poses: int = 6
    settle_s: float = 5.0
    pose_error_deg: float = 3.0

    def __post_init__(self) -> None:
        if not (self.total_s > 0 and self.rate_hz > 0 and self.settle_s >= 0):
            raise ValueError("total_s and rate_hz must be positive, settle_s >= 0")
        if self.poses < 6:
            raise ValueError("a static calibration of six unknowns needs >= 6 poses")

    @property
    def usable_per_pose_s(self) -> float:
        """Seconds of still data per pose: T/P − settle time."""
        return self.total_s / self.poses - self.settle_s

    @property
    def samples_per_pose(self) -> int:
        """Samples averaged per pose (0 if the settle time eats the budget)."""
        return max(0, int(np.floor(self.usable_per_pose_s * self.rate_hz + 1e-9)))

    @property
    def feasible(self) -> bool:
        """Whether every pose keeps at least one sample."""
        return self.samples_per_pose > 0


def nominal_directions(poses: int) -> np.ndarray:
    """Unit vectors of the poses: ±x, ±y, ±z, then the cube's corners (for P > 6)."""
    faces = np.vstack([np.eye(3), -np.eye(3)])[[0, 3, 1, 4, 2, 5]]
    corners = np.array(
        [[sx, sy, sz] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)], dtype=float
    ) / np.sqrt(3.0)
    extra = [corners[i % 8] for i in range(poses - 6)]
    return np.vstack([faces, *extra]) if extra else faces


def perturbed_directions(poses: int, error_deg: float, rng: np.random.Generator) -> np.ndarray:
    """Nominal poses each turned by a random rotation of RMS angle ``error_deg``."""
    nominal = nominal_directions(poses)
    rotvecs = rng.standard_normal((poses, 3)) * np.deg2rad(error_deg) / np.sqrt(3.0)
    return np.array([exp_so3(r) @ u for r, u in zip(rotvecs, nominal, strict=True)])


def _mean_std_mps2(noise: NoiseSpec, rate_hz: float, samples: int) -> np.ndarray:
    """Std of the mean of ``samples`` noise samples per axis (long-run variance for AR)."""
    a = noise.ar_polynomial(rate_hz)
    return noise.innovation_std(rate_hz) / abs(float(np.sum(a))) / np.sqrt(samples)


def simulate_pose_means(
    sensor: SensorParams,
    plan: StaticPlan,
    noise: NoiseSpec,
    rng: np.random.Generator,
    gravity_mps2: float = STANDARD_GRAVITY_MPS2,
) -> np.ndarray:
    """Draw the P pose means m_i = o + Γ g u_i + mean noise (eq. 5 at rest).

    For white noise the mean of n samples is drawn directly (N(0, σ²/n), exact
    in distribution); coloured noise is sampled in full and averaged.
    """
    if not plan.feasible:
        raise ValueError(
            f"{plan.total_s:g} s over {plan.poses} poses leaves no still data after "
            f"{plan.settle_s:g} s of settling per pose"
        )
    u = perturbed_directions(plan.poses, plan.pose_error_deg, rng)
    clean = sensor.offset_mps2 + gravity_mps2 * u * sensor.gain
    n = plan.samples_per_pose
    if noise.bandwidth_hz is None:
        return clean + rng.standard_normal(clean.shape) * noise.std / np.sqrt(n)
    return clean + np.array([noise.sample(n, plan.rate_hz, rng).mean(axis=0) for _ in u])


@dataclass(frozen=True, eq=False)
class StaticEstimate:
    """Offsets and gains of a static calibration."""

    offset_mps2: np.ndarray
    gain: np.ndarray
    iterations: int

    def values(self) -> np.ndarray:
        """(o_x, o_y, o_z, γ_x, γ_y, γ_z), in :data:`STATIC_NAMES` order."""
        return np.concatenate([self.offset_mps2, self.gain])


def fit_ellipsoid(means: np.ndarray, gravity_mps2: float = STANDARD_GRAVITY_MPS2):
    """Axis-aligned ellipsoid through the pose means (module docstring): (o, γ)."""
    m = np.asarray(means, dtype=float)
    design = np.column_stack([m**2, m, np.ones(len(m))])
    coef = np.linalg.svd(design)[2][-1]
    a, b, c = coef[:3], coef[3:6], coef[6]
    if np.all(a < 0):
        a, b, c = -a, -b, -c
    if not np.all(a > 0):
        raise ValueError("the pose means do not lie on an ellipsoid (poses not spread)")
    offset = -b / (2 * a)
    k = float(np.sum(b**2 / (4 * a)) - c)
    if k <= 0:
        raise ValueError("degenerate ellipsoid fit")
    return offset, np.sqrt(k / a) / gravity_mps2


def fit_static(
    means: np.ndarray, gravity_mps2: float = STANDARD_GRAVITY_MPS2, max_iterations: int = 20
) -> StaticEstimate:
    """|a| = g least squares (S1) by Gauss–Newton, started from :func:`fit_ellipsoid`."""
    m = np.asarray(means, dtype=float)
    offset, gain = fit_ellipsoid(m, gravity_mps2)
    x = np.concatenate([offset, gain])
    iterations = 0
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (count is reported)
        s = (m - x[:3]) / x[3:]  # Γ⁻¹(m − o)
        norm = np.linalg.norm(s, axis=1)
        resid = norm - gravity_mps2
        unit = s / norm[:, None]
        jac = np.hstack([-unit / x[3:], -unit * s / x[3:]])  # ∂‖s‖/∂o, ∂‖s‖/∂γ
        step = np.linalg.lstsq(jac, -resid, rcond=None)[0]
        x = x + step
        if np.max(np.abs(step)) < 1e-13 * max(1.0, np.max(np.abs(x))):
            break
    return StaticEstimate(offset_mps2=x[:3], gain=x[3:], iterations=iterations)


def static_bound(
    sensor: SensorParams,
    plan: StaticPlan,
    noise: NoiseSpec,
    gravity_mps2: float = STANDARD_GRAVITY_MPS2,
) -> np.ndarray:
    """CRLB covariance of (o, γ) with unknown pose directions (module docstring), 6×6."""
    if not plan.feasible:
        raise ValueError("infeasible static plan (no still data per pose)")
    std = _mean_std_mps2(noise, plan.rate_hz, plan.samples_per_pose)
    fisher = np.zeros((6, 6))
    for u in nominal_directions(plan.poses):
        # Tangent basis of the sphere at u: the pose's two nuisance directions.
        t = np.linalg.svd(u[None, :])[2][1:].T
        j_theta = np.hstack([np.eye(3), gravity_mps2 * np.diag(u)])  # ∂m/∂(o, γ)
        j_u = gravity_mps2 * sensor.gain[:, None] * t  # ∂m/∂(pose), Γ g t
        a_t = j_theta / std[:, None]
        a_u = j_u / std[:, None]
        proj = a_u @ np.linalg.solve(a_u.T @ a_u, a_u.T)
        fisher += a_t.T @ (np.eye(3) - proj) @ a_t
    return np.linalg.inv(fisher)


@dataclass(frozen=True, eq=False)
class StaticMonteCarlo:
    """Spread of the static fit over noise (and pose) realisations."""

    plan: StaticPlan
    sigma_mps2: float
    errors: np.ndarray  # (runs, 6), STATIC_NAMES order
    bound_std: np.ndarray
    failures: int

    @property
    def std(self) -> np.ndarray:
        """Observed spread (ddof = 1)."""
        return self.errors.std(axis=0, ddof=1)

    @property
    def bias(self) -> np.ndarray:
        """Mean error."""
        return self.errors.mean(axis=0)


def static_monte_carlo(
    sensor: SensorParams,
    plan: StaticPlan,
    noise: NoiseSpec,
    realisations: int,
    rng: np.random.Generator,
    gravity_mps2: float = STANDARD_GRAVITY_MPS2,
) -> StaticMonteCarlo:
    """Simulate and fit the static calibration ``realisations`` times."""
    truth = np.concatenate([sensor.offset_mps2, sensor.gain])
    errors = []
    failures = 0
    for _ in range(realisations):
        means = simulate_pose_means(sensor, plan, noise, rng, gravity_mps2)
        try:
            errors.append(fit_static(means, gravity_mps2).values() - truth)
        except (ValueError, np.linalg.LinAlgError):
            failures += 1
    if not errors:
        raise RuntimeError("every static fit failed")
    return StaticMonteCarlo(
        plan=plan,
        sigma_mps2=float(np.mean(noise.std)),
        errors=np.array(errors),
        bound_std=np.sqrt(np.diag(static_bound(sensor, plan, noise, gravity_mps2))),
        failures=failures,
    )
