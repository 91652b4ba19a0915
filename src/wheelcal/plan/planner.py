"""Predicted precision of a planned setup: the bound, the budget, the warnings, the choices.

The joint fit (:mod:`wheelcal.estimate.joint.fit`) attains the Cramér–Rao bound, and
the σ it reports on a real recording *is* that bound evaluated at its estimate
(inverse Fisher information of the whitened problem).  So the σ a user will
see is predictable before the bench is built: the bound at the planned truth
for the planned sampling and noise.  :func:`plan_report` gathers

* the statistical σ of every reported parameter — exact, every sample used;
* the systematic budget (:mod:`wheelcal.plan.budget`): what r, α, g and the
  sample clock do to the parameters, which repeating the calibration does not
  average away;
* the warnings ``calibrate`` would print for such a recording
  (:func:`wheelcal.estimate.joint.identifiability.check_identifiability`), plus the
  planning ones (clipping, discrete twins, too few turns);
* optionally the best mounting (:mod:`wheelcal.plan.mounting`) and the
  geometry-mode trade-offs (:mod:`wheelcal.plan.tradeoff`);
* the mountings the gyroscope's full matrix needs, with its predicted σ
  (:mod:`wheelcal.plan.gyro_plan`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from wheelcal.estimate.joint import (
    Identifiability,
    check_identifiability,
    choose_twin,
    nuisance_columns,
)
from wheelcal.model import EULER_CONVENTION
from wheelcal.plan.bench_plan import PlannedSetup
from wheelcal.plan.budget import PlanBudget, plan_budget
from wheelcal.plan.fisher import bound_from_fisher, fisher_information
from wheelcal.plan.gyro_plan import GyroPlan, plan_gyro
from wheelcal.plan.mounting import MountingResult, MountingSearch
from wheelcal.plan.tradeoff import DEFAULT_TILTS_DEG, TradeoffRow, geometry_tradeoffs
from wheelcal.simulate import GyroSpec

FORMAT = "wheelcal.plan/1"
#: Fewer turns than this leave the spin polynomial and the offsets poorly sampled.
MIN_TURNS = 20.0
#: Systematic above this multiple of the statistical σ is called dominant.
DOMINANT_RATIO = 3.0


@dataclass(frozen=True, eq=False)
class PlanReport:
    """Everything the planner predicts for one setup."""

    setup: PlannedSetup
    names: tuple[str, ...]
    values: np.ndarray
    std: np.ndarray  # Cramér–Rao bound at the planned truth
    budget: PlanBudget
    identifiability: Identifiability
    warnings: tuple[str, ...]
    notes: tuple[str, ...]
    mounting: MountingResult | None
    tradeoffs: tuple[TradeoffRow, ...]
    #: The gyroscope's full matrix: the mountings it needs and its predicted σ.
    gyro: GyroPlan | None = None

    def std_of(self, name: str) -> float:
        """Predicted statistical σ of one parameter."""
        return float(self.std[self.names.index(name)])

    def parameters(self) -> dict[str, dict[str, float]]:
        """``{name: {"value", "std", "systematic_std"}}`` (CONTRACT names)."""
        systematic = self.budget.total_std
        return {
            n: {"value": float(v), "std": float(s), "systematic_std": float(y)}
            for n, v, s, y in zip(self.names, self.values, self.std, systematic, strict=True)
        }

    def to_dict(self) -> dict:
        """The JSON document of ``wheelcal plan --json``."""
        sources = {}
        for s in self.budget.sources:
            sources[s.name] = {
                "unit": s.unit,
                "std": s.std,
                "linear": _named(self.names, s.linear),
                "first_order": _named(self.names, s.first_order),
                "second_order": _named(self.names, s.second_order),
                "shift_plus_1sigma": _named(self.names, s.shift_plus),
                "shift_minus_1sigma": _named(self.names, s.shift_minus),
            }
        return _json_ready(
            {
                "format": FORMAT,
                "setup": self.setup.to_dict(),
                "euler_convention": EULER_CONVENTION,
                "method": {
                    "statistical": "Cramér–Rao bound at the planned truth, every sample "
                    "(the σ the joint fit reports on such a recording)",
                    "systematic": "exact null-space map (eq. 9-13) at ±1σ of each source: "
                    "first order (Δ(+σ) − Δ(−σ))/2, second order (Δ(+σ) + Δ(−σ))/2; "
                    "'linear' is the joint fit's linearised budget",
                },
                "parameters": self.parameters(),
                "systematic": {
                    "total_std": _named(self.names, self.budget.total_std),
                    "sources": sources,
                    "notes": list(self.budget.notes),
                },
                "warnings": list(self.warnings),
                "notes": list(self.notes),
                "poorly_determined": list(self.identifiability.poorly_determined),
                "mounting_search": None if self.mounting is None else self.mounting.to_dict(),
                "tradeoffs": [row.to_dict() for row in self.tradeoffs],
                "gyro": None if self.gyro is None else self.gyro.to_dict(),
            }
        )


def plan_report(
    setup: PlannedSetup,
    search: MountingSearch | None = None,
    tradeoff_tilts_deg: tuple[float, ...] | None = DEFAULT_TILTS_DEG,
    gyro: GyroSpec | None = None,
    gyro_sessions: int = 3,
) -> PlanReport:
    """Predict the precision of ``setup`` (module docstring).

    Parameters
    ----------
    setup:
        The planned bench, sensor, spin and sampling.
    search:
        Run this mounting search (the mounting is free); ``None``: keep the plan's.
    tradeoff_tilts_deg:
        Tilts of the geometry trade-off table; ``None`` skips it.
    gyro, gyro_sessions:
        The IMU's gyroscope (default: a typical MEMS part's noise) and the spins per
        mounting planned for its full matrix (:mod:`wheelcal.plan.gyro_plan`).
    """
    params = setup.params()
    layout = setup.layout()
    times = setup.centred_times_s()
    with threadpool_limits(1):  # small products: BLAS threads only contend
        fisher = fisher_information(
            params, times, setup.noise_model(), layout, tuple(nuisance_columns(layout))
        )
    bound = bound_from_fisher(params, layout, fisher)
    budget = plan_budget(setup, fisher)
    ident = check_identifiability(params, times, bound.names, bound.std)
    warnings = list(ident.warnings) + _planning_warnings(setup)
    notes = _notes(setup, bound.names, bound.std, budget)
    mounting = search.run(setup) if search is not None else None
    tradeoffs = () if tradeoff_tilts_deg is None else geometry_tradeoffs(setup, tradeoff_tilts_deg)
    return PlanReport(
        setup=setup,
        names=bound.names,
        values=bound.values,
        std=bound.std,
        budget=budget,
        identifiability=ident,
        warnings=tuple(warnings),
        notes=tuple(notes),
        mounting=mounting,
        tradeoffs=tradeoffs,
        gyro=plan_gyro(setup, sessions=gyro_sessions, gyro=gyro),
    )


def _planning_warnings(setup: PlannedSetup) -> list[str]:
    out = []
    if setup.full_scale_g is not None:
        peak_g = setup.peak_accel_mps2 / setup.gravity_mps2
        if peak_g >= setup.full_scale_g:
            out.append(
                f"the sensor will clip: up to {peak_g:.1f} g at {setup.omega_start_radps:g} rad/s "
                f"(range ±{setup.full_scale_g:g} g) — spin slower or mount nearer the axle"
            )
    twin = choose_twin(setup.params())
    if setup.geometry != "vertical" and twin.ambiguous:
        out.append(
            f"tilt {setup.tilt_deg:g}° is close to vertical: the two discrete twins have "
            "offsets too similar to tell apart (plan a smaller tilt, or a vertical wheel)"
        )
    if setup.turns < MIN_TURNS:
        out.append(
            f"only {setup.turns:.0f} wheel turns in the window: record longer (≥ {MIN_TURNS:.0f})"
        )
    return out


def _notes(setup: PlannedSetup, names, std, budget: PlanBudget) -> list[str]:
    out = list(budget.notes)
    total = budget.total_std
    for group, label in (("offset_", "offsets"), ("gain_", "gains")):
        idx = [i for i, n in enumerate(names) if n.startswith(group)]
        ratio = float(np.max(total[idx] / std[idx]))
        if ratio > DOMINANT_RATIO:
            top = max(budget.sources, key=lambda s: float(np.max(s.rms[idx])))
            out.append(
                f"{label}: the systematic error (mostly {top.name} ±{top.std:g} {top.unit}) is "
                f"up to {ratio:.0f}× the statistical σ — repeating the calibration will not "
                "reduce it"
            )
    for source in budget.sources:
        for group, label in (("gain_", "gains"), ("offset_", "offsets")):
            idx = [i for i, n in enumerate(names) if n.startswith(group)]
            first = float(np.max(np.abs(source.first_order[idx])))
            second_values = np.abs(source.second_order[idx])
            if np.all(np.isnan(second_values)):
                continue
            second = float(np.nanmax(second_values))
            if second > 0.1 * first and second > 1e-9:
                out.append(
                    f"{label}: {source.name} ±{source.std:g} {source.unit} moves them by "
                    f"{_signed(source.second_order[idx])} at second order (½f″σ², the mean "
                    f"shift), against {first:.2g} at first order"
                    + (" — the linearised budget misses it" if first < 1e-9 else "")
                )
    if setup.geometry in ("tilt", "vertical"):
        out.append(
            "tilt/vertical mode: the gains scale with the assumed gravity (Γ' = Γ g/g'), so "
            "give local gravity (gravity_mps2) to the calibration"
        )
    return out


def _signed(values: np.ndarray) -> str:
    worst = values[int(np.nanargmax(np.abs(values)))]
    return f"{worst:+.2g}"


def _json_ready(value):
    """Plain Python types; non-finite numbers (an unidentifiable σ) become None."""
    if isinstance(value, dict):
        return {k: _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def _named(names: tuple[str, ...], values: np.ndarray) -> dict[str, float | None]:
    return {n: (float(v) if np.isfinite(v) else None) for n, v in zip(names, values, strict=True)}
