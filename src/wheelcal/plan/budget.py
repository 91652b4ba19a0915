"""Systematic budget of a plan: the joint fit's linear budget plus the second-order term.

The linear budget is the estimator's own (:func:`wheelcal.estimate.systematic.
systematic_budget`, first derivative of the fit w.r.t. each fixed quantity), so
``plan`` and ``calibrate`` print the same numbers.  It misses what is zero to
first order — above all the gains of a vertical wheel, which a levelling error
δ moves by −δ²/2 only.  The exact map of :mod:`wheelcal.plan.absorb` gives, for
an error e of one source with standard deviation σ,

    Δ(e) = f′e + ½f″e² + …,
    first order  f′σ ≈ (Δ(+σ) − Δ(−σ)) / 2    (odd part; = the linear budget),
    second order ½f″σ² ≈ (Δ(+σ) + Δ(−σ)) / 2  (even part: the mean shift over e ~ N(0, σ²)),

and the RMS shift √(f′²σ² + 3(½f″σ²)²) of a Gaussian error, which is what the
planner adds in quadrature over the (independent) sources.  The odd part agrees
with the estimator's linear budget on every sensor and bench parameter (tests);
it differs only on the spin coefficients under a clock error, which the linear
budget treats as a pure radius error although ω_k are read in the clock's
seconds too (ω_k changes by (k+1)ε).  Where the exact map has no solution
(radius mode close to a vertical wheel) the linear budget is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint import (
    SystematicBudget,
    nuisance_columns,
    report_transform,
    systematic_budget,
)
from wheelcal.plan.absorb import AssumedErrors, NotAbsorbable, reported_shift
from wheelcal.plan.bench_plan import PlannedSetup


@dataclass(frozen=True, eq=False)
class SourceEffect:
    """One unseen quantity: its σ, and the parameter shifts it causes (reported names)."""

    name: str
    unit: str
    std: float
    linear: np.ndarray  # the estimator's f′σ (assumed value σ too high)
    first_order: np.ndarray  # odd part of the exact map; the linear budget where it fails
    second_order: np.ndarray  # ½f″σ²; NaN where the exact map has no solution
    shift_plus: np.ndarray  # exact Δ(+σ); NaN where the exact map has no solution
    shift_minus: np.ndarray  # exact Δ(−σ)

    @property
    def rms(self) -> np.ndarray:
        """RMS shift over a Gaussian error of this σ (first and second order)."""
        second = np.nan_to_num(self.second_order, nan=0.0)
        return np.sqrt(self.first_order**2 + 3.0 * second**2)


@dataclass(frozen=True, eq=False)
class PlanBudget:
    """Systematic effects of every source on the reported parameters."""

    names: tuple[str, ...]
    linear: SystematicBudget
    sources: tuple[SourceEffect, ...]
    notes: tuple[str, ...] = ()

    @property
    def total_std(self) -> np.ndarray:
        """Root-sum-square over sources of the RMS shifts."""
        if not self.sources:
            return np.zeros(len(self.names))
        return np.sqrt(sum(s.rms**2 for s in self.sources))

    def std_of(self, name: str) -> float:
        """Total systematic σ of one reported parameter."""
        return float(self.total_std[self.names.index(name)])

    def source(self, name: str) -> SourceEffect:
        """One source by name (``radius``, ``tilt``, ``gravity``, ``sample_clock``)."""
        for s in self.sources:
            if s.name == name:
                return s
        raise KeyError(name)


def plan_budget(setup: PlannedSetup, hessian: np.ndarray) -> PlanBudget:
    """Linear (estimator) budget and exact second-order terms for a plan.

    Parameters
    ----------
    setup:
        The plan.
    hessian:
        J̃ᵀJ̃ over [free parameters | nuisance columns of the layout], as from
        :func:`wheelcal.plan.fisher.fisher_information` with
        ``nuisances=nuisance_columns(layout)``.
    """
    params = setup.params()
    layout = setup.layout()
    nuisances = nuisance_columns(layout)
    names, _, g = report_transform(params, layout)
    linear = systematic_budget(
        params,
        layout,
        hessian,
        nuisances,
        g,
        names,
        radius_std_m=setup.radius_std_m,
        gravity_std_mps2=setup.gravity_std_mps2,
        clock_std_ppm=setup.clock_std_ppm,
        tilt_std_deg=setup.tilt_std_deg,
    )
    effects, notes = [], []
    for source in linear.sources:
        linear_shift = source.shift_per_unit * source.std
        try:
            plus = reported_shift(
                params, setup.geometry, layout, AssumedErrors.single(source.name, source.std)
            )
            minus = reported_shift(
                params, setup.geometry, layout, AssumedErrors.single(source.name, -source.std)
            )
            first, second = 0.5 * (plus - minus), 0.5 * (plus + minus)
        except NotAbsorbable as exc:
            plus = minus = second = np.full(len(names), np.nan)
            first = linear_shift
            notes.append(f"{source.name} ±{source.std:g} {source.unit}: {exc}")
        effects.append(
            SourceEffect(
                name=source.name,
                unit=source.unit,
                std=source.std,
                linear=linear_shift,
                first_order=first,
                second_order=second,
                shift_plus=plus,
                shift_minus=minus,
            )
        )
    return PlanBudget(names=names, linear=linear, sources=tuple(effects), notes=tuple(notes))
