"""Plan a calibration bench before building it: predicted σ, systematic budget, best mounting.

Layer 7 (above ``calibration``, beside ``viz``, below ``batch`` and ``study``).

Layers: :mod:`~wheelcal.plan.bench_plan` (the planned truth) →
:mod:`~wheelcal.plan.fisher` (exact and decimated Fisher information) →
:mod:`~wheelcal.plan.absorb` (exact null-space map of a wrong fixed quantity) →
:mod:`~wheelcal.plan.budget`, :mod:`~wheelcal.plan.mounting`,
:mod:`~wheelcal.plan.tradeoff` → :mod:`~wheelcal.plan.planner` →
:mod:`~wheelcal.plan.text` (the terminal table).
"""

from wheelcal.estimate.joint import decimation_stride
from wheelcal.plan.absorb import AssumedErrors, absorbed_fit, reported_shift
from wheelcal.plan.bench_plan import PAPER_MOUNTING_EULER_DEG, PlannedSetup, drag_spin
from wheelcal.plan.budget import PlanBudget, SourceEffect, plan_budget
from wheelcal.plan.fisher import bound_from_fisher, fisher_information
from wheelcal.plan.mounting import MountingChoice, MountingResult, MountingSearch
from wheelcal.plan.planner import PlanReport, plan_report
from wheelcal.plan.text import render
from wheelcal.plan.tradeoff import DEFAULT_TILTS_DEG, TradeoffRow, geometry_tradeoffs

__all__ = [
    "DEFAULT_TILTS_DEG",
    "PAPER_MOUNTING_EULER_DEG",
    "AssumedErrors",
    "MountingChoice",
    "MountingResult",
    "MountingSearch",
    "PlanBudget",
    "PlanReport",
    "PlannedSetup",
    "SourceEffect",
    "TradeoffRow",
    "absorbed_fit",
    "bound_from_fisher",
    "decimation_stride",
    "drag_spin",
    "fisher_information",
    "geometry_tradeoffs",
    "plan_budget",
    "plan_report",
    "render",
    "reported_shift",
]
