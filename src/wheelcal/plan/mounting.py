"""The sensor mounting (and tilt) that minimise the offset σ — the paper's weakest parameter.

Pedersini (Sec. IV-A) finds σ_o ≈ 20 σ_γ and blames the kinematics: an axis
that sees a unipolar signal cannot separate its offset from its gain.  How the
sensor sits on the wheel (R of eq. 4) decides which axes see the bipolar
g sin α cos ϑ and the slowly varying r ω², so the Cramér–Rao bound of the
offsets depends strongly on R, and on the tilt α.

The objective is the offset σ of the *worst* sensor axis (statistical, or
statistical ⊕ first-order systematic with ``objective="total"``).  Not the RMS
over axes: the offset covariance turns with the sensor, C_sensor ≈ R C_bench Rᵀ,
so its trace hardly depends on R — what a good mounting does is share the
poorly determined bench direction (along the wheel axis Z, where a_Z = g cos α
is a constant like the offset, paper II-C) among all three axes instead of
leaving it to one, and decouple offsets from gains.  The worst-axis σ is
invariant when the sensor is turned by a proper signed permutation of its
axes (s → P s: relabelled axes, same information on each), so every optimum
comes in 24 physically different mountings; the one closest to the user's
reference mounting is reported.

Search (seconds): Haar-random rotations at the planned tilt on the decimated
grid of :mod:`wheelcal.plan.fisher`, Nelder–Mead refinements of the best few
over a local rotation vector, then — where the tilt is the user's to choose
(``radius`` and ``tilt`` modes) — a coarse tilt scan and a joint refinement of
mounting and tilt.  The winners are re-evaluated on the full grid.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from scipy import optimize
from threadpoolctl import threadpool_limits

from wheelcal.estimate.joint import (
    SAMPLES_PER_TURN,
    covariance_from_fisher,
    decimation_stride,
    nuisance_columns,
)
from wheelcal.model import BenchParams, Rotation
from wheelcal.plan.bench_plan import PlannedSetup
from wheelcal.plan.fisher import fisher_information
from wheelcal.simulate import random_rotation

OBJECTIVES = ("statistical", "total")


def _axis_permutations() -> tuple[np.ndarray, ...]:
    """The 24 proper signed permutation matrices (rotations of a cube)."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[range(3), perm] = signs
            if np.linalg.det(m) > 0:
                out.append(m)
    return tuple(out)


AXIS_PERMUTATIONS = _axis_permutations()


@dataclass(frozen=True, eq=False)
class MountingChoice:
    """A mounting and tilt with its full-grid offset and gain σ."""

    euler_deg: np.ndarray
    tilt_deg: float
    offset_std_mps2: np.ndarray  # statistical, per axis
    offset_systematic_mps2: np.ndarray  # first-order systematic, per axis
    gain_std: np.ndarray
    objective: float

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "euler_deg": [float(e) for e in self.euler_deg],
            "tilt_deg": float(self.tilt_deg),
            "offset_std_mps2": self.offset_std_mps2.tolist(),
            "offset_systematic_mps2": self.offset_systematic_mps2.tolist(),
            "gain_std": self.gain_std.tolist(),
            "objective_mps2": float(self.objective),
        }


@dataclass(frozen=True, eq=False)
class MountingResult:
    """Outcome of a mounting search."""

    objective: str
    reference: MountingChoice
    best_at_plan_tilt: MountingChoice
    best: MountingChoice | None  # None when the tilt is fixed (vertical wheel)
    random_median: float  # objective of a mounting chosen at random (median, decimated grid)
    evaluations: int
    stride: int

    @property
    def overall(self) -> MountingChoice:
        """The best choice found (with free tilt when allowed)."""
        return self.best if self.best is not None else self.best_at_plan_tilt

    @property
    def improvement(self) -> float:
        """Objective of the reference over that of the overall best (> 1 = better)."""
        return self.reference.objective / self.overall.objective

    @property
    def improvement_at_plan_tilt(self) -> float:
        """The same gain keeping the planned tilt."""
        return self.reference.objective / self.best_at_plan_tilt.objective

    def to_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "objective": self.objective,
            "reference": self.reference.to_dict(),
            "best_at_plan_tilt": self.best_at_plan_tilt.to_dict(),
            "best": None if self.best is None else self.best.to_dict(),
            "improvement": self.improvement,
            "improvement_at_plan_tilt": self.improvement_at_plan_tilt,
            "random_mounting_median_objective_mps2": self.random_median,
            "evaluations": self.evaluations,
            "decimation_stride": self.stride,
        }


@dataclass(frozen=True)
class MountingSearch:
    """Configuration of the search (module docstring); :meth:`run` returns the result.

    Parameters
    ----------
    candidates:
        Haar-random rotations tried at the planned tilt.
    refine:
        How many of the best candidates get a local refinement.
    free_tilt:
        Also choose the tilt (ignored for a vertical wheel).
    tilt_range_deg:
        Tilts allowed when the tilt is free.  Near 0° the phase is unobservable
        (g sin α → 0); near 90° the discrete twins merge (CONTRACT).
    objective:
        ``statistical`` (worst-axis offset σ) or ``total`` (⊕ first-order systematic).
    samples_per_turn:
        Resolution of the decimated grid (:func:`~wheelcal.plan.fisher.decimation_stride`).
    seed:
        Seed of the random candidates (the search is deterministic).
    max_evaluations:
        Budget of each Nelder–Mead refinement.
    """

    candidates: int = 192
    refine: int = 3
    free_tilt: bool = True
    tilt_range_deg: tuple[float, float] = (10.0, 80.0)
    objective: str = "statistical"
    samples_per_turn: float = SAMPLES_PER_TURN
    seed: int = 0
    max_evaluations: int = 250
    tilt_scan_deg: tuple[float, ...] = field(default=(15.0, 25.0, 35.0, 45.0, 55.0, 65.0, 75.0))

    def __post_init__(self) -> None:
        if self.objective not in OBJECTIVES:
            raise ValueError(f"objective must be one of {OBJECTIVES}, got {self.objective!r}")
        lo, hi = self.tilt_range_deg
        if not 0.0 < lo < hi < 90.0:
            raise ValueError(f"tilt_range_deg must satisfy 0 < low < high < 90, got {lo}, {hi}")
        if self.candidates < 1 or self.refine < 1:
            raise ValueError("need at least one candidate and one refinement")

    def run(self, setup: PlannedSetup) -> MountingResult:
        """Search the mounting (and tilt) that minimise the objective for ``setup``."""
        # Thousands of small matrix products: BLAS threads only contend.
        with threadpool_limits(1):
            return self._run(setup)

    def _run(self, setup: PlannedSetup) -> MountingResult:
        stride = decimation_stride(setup.rate_hz, setup.omega_start_radps, self.samples_per_turn)
        cost = _Objective(setup, stride, self.objective)
        reference = setup.mounting
        plan_tilt = setup.tilt_deg
        rng = np.random.default_rng(self.seed)
        rotations = [random_rotation(rng) for _ in range(self.candidates)]
        values = np.array([cost(r, plan_tilt) for r in rotations])
        random_median = float(np.median(values))
        starts = [reference] + [rotations[i] for i in np.argsort(values)[: self.refine]]

        best_rot, best_val = reference, cost(reference, plan_tilt)
        for start in starts:
            rot, val = self._refine(cost, start, plan_tilt)
            if val < best_val:
                best_rot, best_val = rot, val
        at_plan_tilt = _closest_equivalent(best_rot, reference)

        overall = None
        if self.free_tilt and setup.geometry != "vertical":
            lo, hi = self.tilt_range_deg
            scan = [t for t in self.tilt_scan_deg if lo <= t <= hi] + [plan_tilt]
            start_tilt = min(scan, key=lambda t: cost(best_rot, t))
            rot, tilt, _ = self._refine_with_tilt(cost, best_rot, start_tilt)
            overall = (_closest_equivalent(rot, reference), tilt)

        exact = _Objective(setup, 1, self.objective)
        return MountingResult(
            objective=self.objective,
            reference=exact.choice(reference, plan_tilt),
            best_at_plan_tilt=exact.choice(at_plan_tilt, plan_tilt),
            best=None if overall is None else exact.choice(*overall),
            random_median=random_median,
            evaluations=cost.evaluations,
            stride=stride,
        )

    def _refine(self, cost, start: Rotation, tilt_deg: float):
        def f(delta):
            return np.log(cost(start.perturbed(delta), tilt_deg))

        res = optimize.minimize(
            f,
            np.zeros(3),
            method="Nelder-Mead",
            options={
                "xatol": 1e-3,
                "fatol": 1e-4,
                "maxfev": self.max_evaluations,
                "initial_simplex": _simplex(3, 0.3),
            },
        )
        return start.perturbed(res.x), float(np.exp(res.fun))

    def _refine_with_tilt(self, cost, start: Rotation, tilt_deg: float):
        lo, hi = self.tilt_range_deg
        scale = 30.0  # degrees of tilt per unit of the search variable (≈ rad of rotation)

        def f(x):
            return np.log(cost(start.perturbed(x[:3]), x[3] * scale))

        simplex = _simplex(4, 0.2) + np.array([0.0, 0.0, 0.0, tilt_deg / scale])
        simplex[:, 3] = np.clip(simplex[:, 3], lo / scale, hi / scale)
        res = optimize.minimize(
            f,
            simplex[0],
            method="Nelder-Mead",
            bounds=[(None, None)] * 3 + [(lo / scale, hi / scale)],
            options={
                "xatol": 1e-3,
                "fatol": 1e-4,
                "maxfev": 2 * self.max_evaluations,
                "initial_simplex": simplex,
            },
        )
        return start.perturbed(res.x[:3]), float(res.x[3] * scale), float(np.exp(res.fun))


def _simplex(dim: int, step: float) -> np.ndarray:
    return np.vstack([np.zeros(dim), step * np.eye(dim)])


def _closest_equivalent(rotation: Rotation, reference: Rotation) -> Rotation:
    """The P·R (P a proper signed axis permutation) nearest to the reference mounting."""
    options = [Rotation(p @ rotation.matrix) for p in AXIS_PERMUTATIONS]
    return min(options, key=reference.angle_to)


class _Objective:
    """Worst-axis offset σ of a plan with another mounting and tilt (counts evaluations)."""

    def __init__(self, setup: PlannedSetup, stride: int, objective: str) -> None:
        self.setup = setup
        self.stride = stride
        self.objective = objective
        self.params = setup.params()
        self.times = setup.centred_times_s()
        self.noise = setup.noise_model()
        self.layout = setup.layout()
        self.nuisances = tuple(nuisance_columns(self.layout))
        self.offsets = self.layout.blocks["offset"]
        self.gains = self.layout.blocks["gain"]
        self.evaluations = 0

    def _terms(self, rotation: Rotation, tilt_deg: float):
        self.evaluations += 1
        bench = BenchParams(
            tilt_rad=np.deg2rad(tilt_deg),
            radius_m=self.params.bench.radius_m,
            misalignment=rotation,
        )
        params = self.params.with_changes(bench=bench)
        nuisances = self.nuisances
        fisher = fisher_information(
            params, self.times, self.noise, self.layout, nuisances, self.stride
        )
        size = self.layout.size
        cov = covariance_from_fisher(fisher[:size, :size])
        offset_std = np.sqrt(np.diag(cov)[self.offsets])
        gain_std = np.sqrt(np.diag(cov)[self.gains])
        systematic = np.zeros(3)
        if np.all(np.isfinite(cov)):
            for k, name in enumerate(nuisances):
                per_unit = -(cov @ fisher[:size, size + k])[self.offsets]
                systematic += (per_unit * self._source_std(name, params)) ** 2
        return offset_std, np.sqrt(systematic), gain_std

    def _source_std(self, nuisance: str, params) -> float:
        s = self.setup
        if nuisance == "radius_m":
            # Radius and sample clock (ε ≡ relative radius error −2ε) are independent.
            return float(np.hypot(s.radius_std_m, 2e-6 * s.clock_std_ppm * params.bench.radius_m))
        if nuisance == "tilt_rad":
            return float(np.deg2rad(s.tilt_std_deg))
        return s.gravity_std_mps2

    def _value(self, offset_std, systematic) -> float:
        total = offset_std**2 + (systematic**2 if self.objective == "total" else 0.0)
        value = float(np.sqrt(np.max(total)))  # the worst axis
        return value if np.isfinite(value) else 1e6

    def __call__(self, rotation: Rotation, tilt_deg: float) -> float:
        offset_std, systematic, _ = self._terms(rotation, tilt_deg)
        return self._value(offset_std, systematic)

    def choice(self, rotation: Rotation, tilt_deg: float) -> MountingChoice:
        offset_std, systematic, gain_std = self._terms(rotation, tilt_deg)
        return MountingChoice(
            euler_deg=rotation.euler_deg(),
            tilt_deg=float(tilt_deg),
            offset_std_mps2=offset_std,
            offset_systematic_mps2=systematic,
            gain_std=gain_std,
            objective=self._value(offset_std, systematic),
        )
