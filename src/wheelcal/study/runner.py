"""The accuracy study of Sec. IV-A, run end to end: :func:`run_study` → :class:`StudyResult`.

1. **Noise sweep** (Fig. 7–8, Table I): Table I truth, white noise at every
   level of :class:`~wheelcal.study.config.NoiseSweepConfig`; the joint fit
   and the paper's four steps on the same noise realisations (paired).
2. **Static alternative**: six still poses sharing the same 90 s, at the
   Table I noise levels (:mod:`wheelcal.study.static`).
3. **Duration and rate**: wheel CRLB and static bound against T and rate
   (:mod:`wheelcal.study.duration`), with joint-fit Monte Carlo checks.

Every fit of the study goes to one process pool (one BLAS thread per worker,
:func:`~wheelcal.study.montecarlo.run_fits`), slowest first.  Every seed
derives from ``config.seed``; realisation k at level i uses the same noise for
both estimators.  No printing: ``progress(stage, done, total)`` reports.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint import JointFit
from wheelcal.estimate.paper import PaperEstimator
from wheelcal.simulate import NoiseSpec, Scenario, simulate, table1
from wheelcal.study.config import ESTIMATORS, StudyConfig
from wheelcal.study.duration import (
    SENSOR_NAMES,
    PrecisionPoint,
    drag_scenario,
    precision_point,
)
from wheelcal.study.montecarlo import FitTask, run_fits, scenario_bound, summarise
from wheelcal.study.noise_sweep import LevelStats, level_stats
from wheelcal.study.static import StaticMonteCarlo, StaticPlan, static_monte_carlo

#: progress(stage, done, total); stages: "fits", "bounds", "static".
StudyProgress = Callable[[str, int, int], None]

_SWEEP_STREAM, _CHECK_STREAM, _STATIC_STREAM = 1, 2, 3


def seed_for(master: int, *path: int) -> int:
    """A reproducible, independent seed for one realisation (``path`` names it)."""
    return int(np.random.SeedSequence([master, *path]).generate_state(1, dtype=np.uint32)[0])


def estimator_named(name: str):
    """The estimator configuration behind an output name (``"paper"`` or ``"joint"``)."""
    if name == "paper":
        return PaperEstimator()
    if name == "joint":
        return JointFit()
    raise ValueError(f"unknown estimator {name!r}; choose from {ESTIMATORS}")


@dataclass(frozen=True, eq=False)
class StaticComparison:
    """Six still poses against the wheel: same sensor, noise and time (:data:`SENSOR_NAMES`)."""

    sigma_mps2: float
    static: StaticMonteCarlo
    wheel_joint_std: np.ndarray
    wheel_crlb_std: np.ndarray


@dataclass(frozen=True, eq=False)
class CheckPoint:
    """Monte Carlo check that the joint fit attains the CRLB at one (duration, rate)."""

    duration_s: float
    rate_hz: float
    runs: int
    failures: int
    joint_std: np.ndarray  # SENSOR_NAMES
    crlb_std: np.ndarray
    static: StaticMonteCarlo | None  # None when the static plan is infeasible


@dataclass(frozen=True, eq=False)
class StudyResult:
    """Everything the study measured; :mod:`wheelcal.study.report` serialises it.

    Attributes
    ----------
    sweep:
        Estimator name → its :class:`LevelStats`, one per σ_n (ascending).
    systematic:
        Source → parameter → 1σ shift of the joint fit's estimate at the
        Table I point (radius ±1 mm, gravity, sample clock), for context.
    """

    config: StudyConfig
    scenario: Scenario
    sweep: dict[str, tuple[LevelStats, ...]]
    static: tuple[StaticComparison, ...]
    durations: tuple[PrecisionPoint, ...]
    rates: tuple[PrecisionPoint, ...]
    checks: tuple[CheckPoint, ...]
    systematic: dict[str, dict[str, float]]
    wall_s: float
    fits: int
    workers: int

    @property
    def sigma_levels_mps2(self) -> tuple[float, ...]:
        """σ_n of the sweep."""
        return self.config.noise_sweep.sigma_levels_mps2()

    def level(self, estimator: str, sigma_mps2: float) -> LevelStats:
        """The statistics of ``estimator`` at ``sigma_mps2``."""
        for stats in self.sweep[estimator]:
            if abs(stats.sigma_mps2 - sigma_mps2) < 1e-9:
                return stats
        raise KeyError(f"no level {sigma_mps2} for {estimator}")


def _tasks(config: StudyConfig, base: Scenario):
    """All fits of the study, slowest first, with a key naming each one's group."""
    sweep = config.noise_sweep
    levels = sweep.sigma_levels_mps2()
    scenarios = {s: table1(NoiseSpec(s)) for s in levels}
    keyed: list[tuple[tuple, FitTask]] = []
    for estimator in ("paper", "joint"):
        runs = sweep.realisations_of(estimator)
        est = estimator_named(estimator)
        for i, sigma in sorted(enumerate(levels), key=lambda p: -p[1]):
            for k in range(runs):
                seed = seed_for(config.seed, _SWEEP_STREAM, i, k)
                keyed.append((("sweep", estimator, sigma), (scenarios[sigma], est, seed)))
        if estimator == "paper":
            keyed += _check_tasks(config, base)
    return keyed, scenarios


def _check_points(config: StudyConfig) -> list[tuple[float, float]]:
    d = config.duration
    points = [(t, d.base_rate_hz) for t in d.check_durations_s]
    points += [(d.base_duration_s, r) for r in d.check_rates_hz]
    return list(dict.fromkeys(points))  # no duplicates, order kept


def _drag_scenario(config: StudyConfig, base: Scenario, duration_s: float, rate_hz: float):
    d = config.duration
    return drag_scenario(base, duration_s, rate_hz, d.sigma_mps2, d.start_radps, d.end_radps_at_90s)


def _check_tasks(config: StudyConfig, base: Scenario) -> list[tuple[tuple, FitTask]]:
    d = config.duration
    if d.check_realisations == 0:
        return []
    out = []
    joint = JointFit()
    # Longest recordings first.
    points = sorted(_check_points(config), key=lambda p: -p[0] * p[1])
    for j, (duration, rate) in enumerate(points):
        scenario = _drag_scenario(config, base, duration, rate)
        for k in range(d.check_realisations):
            seed = seed_for(config.seed, _CHECK_STREAM, j, k)
            out.append((("check", duration, rate), (scenario, joint, seed)))
    return out


def _systematic(base: Scenario, seed: int) -> dict[str, dict[str, float]]:
    result = JointFit().fit(simulate(base, np.random.default_rng(seed)).recording)
    budget = result.systematic
    return {
        src.name: {
            n: float(abs(s) * src.std)
            for n, s in zip(budget.names, src.shift_per_unit, strict=True)
            if n in SENSOR_NAMES
        }
        | {"std": float(src.std), "unit": src.unit}
        for src in budget.sources
    }


def run_study(config: StudyConfig, progress: StudyProgress | None = None) -> StudyResult:
    """Run the whole study (module docstring); ``progress`` gets (stage, done, total)."""
    clock = time.perf_counter()

    def report(stage: str, done: int, total: int) -> None:
        if progress is not None:
            progress(stage, done, total)

    base = table1()
    workers = config.workers or os.cpu_count() or 1
    keyed, scenarios = _tasks(config, base)
    outcomes = run_fits([task for _, task in keyed], workers, lambda d, t: report("fits", d, t))
    grouped: dict[tuple, list] = {}
    for (key, _), outcome in zip(keyed, outcomes, strict=True):
        grouped.setdefault(key, []).append(outcome)

    d = config.duration
    levels = config.noise_sweep.sigma_levels_mps2()
    check_points = _check_points(config) if d.check_realisations else []
    total = len(levels) + len(check_points) + len(d.durations_s) + len(d.rates_hz)
    tick = _ticker(report, "bounds", total)
    sweep = _sweep(levels, scenarios, grouped, base.duration_s, tick)
    rng = np.random.default_rng(seed_for(config.seed, _STATIC_STREAM))
    checks = tuple(
        _check(config, base, duration, rate, grouped[("check", duration, rate)], rng, tick)
        for duration, rate in check_points
    )
    duration_points = tuple(
        _precision(config, base, t, d.base_rate_hz, tick) for t in d.durations_s
    )
    rate_points = tuple(_precision(config, base, d.base_duration_s, r, tick) for r in d.rates_hz)
    table_levels = config.noise_sweep.table_levels_mps2
    comparisons = []
    for i, sigma in enumerate(table_levels):
        comparisons.append(_static_comparison(config, base, sweep["joint"], sigma, rng))
        report("static", i + 1, len(table_levels))

    return StudyResult(
        config=config,
        scenario=base,
        sweep={e: tuple(v) for e, v in sweep.items() if v},
        static=tuple(comparisons),
        durations=duration_points,
        rates=rate_points,
        checks=checks,
        systematic=_systematic(base, seed_for(config.seed, _STATIC_STREAM, 1)),
        wall_s=time.perf_counter() - clock,
        fits=len(keyed),
        workers=workers,
    )


def _ticker(report: StudyProgress, stage: str, total: int) -> Callable[[], None]:
    """A function that reports one more step of ``stage`` (of ``total``) each call."""
    done = 0

    def tick() -> None:
        nonlocal done
        done += 1
        report(stage, done, total)

    return tick


def _sweep(
    levels: tuple[float, ...],
    scenarios: dict[float, Scenario],
    grouped: dict[tuple, list],
    duration_s: float,
    tick: Callable[[], None],
) -> dict[str, list[LevelStats]]:
    """Each estimator's statistics at every noise level it ran at (ascending σ_n)."""
    sweep: dict[str, list[LevelStats]] = {e: [] for e in ESTIMATORS}
    for sigma in levels:
        bound = scenario_bound(scenarios[sigma])
        for estimator in ESTIMATORS:
            runs = grouped.get(("sweep", estimator, sigma))
            if runs:
                summary = summarise(bound, runs)
                sweep[estimator].append(
                    level_stats(estimator, sigma, summary, bound.covariance, duration_s)
                )
        tick()
    return sweep


def _static_plan(config: StudyConfig, duration_s: float, rate_hz: float) -> StaticPlan:
    """The six still poses of ``config.static`` sharing ``duration_s`` at ``rate_hz``."""
    s = config.static
    return StaticPlan(duration_s, rate_hz, s.poses, s.settle_s, s.pose_error_deg)


def _check(
    config: StudyConfig,
    base: Scenario,
    duration_s: float,
    rate_hz: float,
    runs: list,
    rng: np.random.Generator,
    tick: Callable[[], None],
) -> CheckPoint:
    """The joint fit's Monte Carlo ``runs`` at one (T, rate) against the CRLB and the poses."""
    summary = summarise(scenario_bound(_drag_scenario(config, base, duration_s, rate_hz)), runs)
    idx = [summary.names.index(n) for n in SENSOR_NAMES]
    plan = _static_plan(config, duration_s, rate_hz)
    static_mc = (
        static_monte_carlo(
            base.truth.sensor,
            plan,
            NoiseSpec(config.duration.sigma_mps2),
            config.static.realisations,
            rng,
        )
        if plan.feasible
        else None
    )
    tick()
    return CheckPoint(
        duration_s=duration_s,
        rate_hz=rate_hz,
        runs=summary.runs,
        failures=summary.failures,
        joint_std=summary.observed_std[idx],
        crlb_std=summary.crlb_std[idx],
        static=static_mc,
    )


def _precision(
    config: StudyConfig,
    base: Scenario,
    duration_s: float,
    rate_hz: float,
    tick: Callable[[], None],
) -> PrecisionPoint:
    """Wheel CRLB and static bound at one (T, rate) of the duration sweep."""
    scenario = _drag_scenario(config, base, duration_s, rate_hz)
    point = precision_point(scenario, config.static.poses, config.static.settle_s)
    tick()
    return point


def _static_comparison(
    config: StudyConfig,
    base: Scenario,
    joint_levels: list[LevelStats],
    sigma_mps2: float,
    rng: np.random.Generator,
) -> StaticComparison:
    """Six still poses in Table I's time at one σ_n against the joint fit's sweep there."""
    joint = next(s for s in joint_levels if abs(s.sigma_mps2 - sigma_mps2) < 1e-9)
    idx = [joint.names.index(n) for n in SENSOR_NAMES]
    plan = _static_plan(config, base.duration_s, base.rate_hz)
    mc = static_monte_carlo(
        base.truth.sensor, plan, NoiseSpec(sigma_mps2), config.static.realisations, rng
    )
    return StaticComparison(
        sigma_mps2=sigma_mps2,
        static=mc,
        wheel_joint_std=joint.std[idx],
        wheel_crlb_std=joint.crlb_std[idx],
    )
