"""What each geometry mode costs, over tilts: statistical σ against systematic shifts.

Eq. (9)–(13) leave one of r, α unknowable from the data, so one must be given,
and its error goes straight into the sensor parameters along the null space
(:mod:`wheelcal.plan.absorb`):

* ``radius`` mode (r measured, α fitted): a relative radius error ε scales the
  gains by 1/(1+ε) and moves offsets along Γ R e_Z by ≈ ε g / cos α; the tilt
  itself is fitted with σ growing like tan α, and with it the offset σ, toward
  a vertical wheel;
* ``tilt`` mode (α measured, r fitted): a levelling error δ moves the gains by
  cot α · δ and the offsets by g δ / sin α;
* ``vertical`` (α = 90° by spirit level): offsets move by g sin δ
  (≈ 0.17 m/s² per degree) but gains only by −δ²/2 (zero to first order).

In the tilt and vertical modes the gains also scale with the assumed gravity
(Γ' = Γ g/g'), so local gravity must be known there.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from wheelcal.estimate.joint import decimation_stride, nuisance_columns
from wheelcal.model import GAIN_NAMES, OFFSET_NAMES
from wheelcal.plan.bench_plan import VERTICAL_TILT_DEG, PlannedSetup
from wheelcal.plan.budget import plan_budget
from wheelcal.plan.fisher import bound_from_fisher, fisher_information

#: Tilts of the trade-off table (the vertical wheel is added as its own row).
DEFAULT_TILTS_DEG = (15.0, 30.0, 45.0, 60.0, 75.0, 85.0)


@dataclass(frozen=True)
class TradeoffRow:
    """Worst-axis offset and gain uncertainties of one geometry mode at one tilt."""

    geometry: str
    tilt_deg: float
    offset_std_mps2: float
    offset_systematic_mps2: float
    gain_std: float
    gain_systematic: float
    gain_second_order: float  # largest |½f″σ²| over sources and axes

    def to_dict(self) -> dict:
        """JSON-ready row: the fields, in order."""
        return asdict(self)


def tradeoff_row(setup: PlannedSetup, stride: int | None = None) -> TradeoffRow:
    """One row: the bound and the budget of ``setup`` (decimated grid unless ``stride=1``)."""
    if stride is None:
        stride = decimation_stride(setup.rate_hz, setup.omega_start_radps)
    params = setup.params()
    layout = setup.layout()
    nuisances = tuple(nuisance_columns(layout))
    fisher = fisher_information(
        params, setup.centred_times_s(), setup.noise_model(), layout, nuisances, stride
    )
    bound = bound_from_fisher(params, layout, fisher)
    budget = plan_budget(setup, fisher)
    std = dict(zip(bound.names, bound.std, strict=True))
    systematic = dict(zip(budget.names, budget.total_std, strict=True))
    gain_idx = [budget.names.index(n) for n in GAIN_NAMES]
    second = [np.nan_to_num(np.abs(s.second_order[gain_idx])) for s in budget.sources]
    return TradeoffRow(
        geometry=setup.geometry,
        tilt_deg=setup.tilt_deg,
        offset_std_mps2=max(std[n] for n in OFFSET_NAMES),
        offset_systematic_mps2=max(systematic[n] for n in OFFSET_NAMES),
        gain_std=max(std[n] for n in GAIN_NAMES),
        gain_systematic=max(systematic[n] for n in GAIN_NAMES),
        gain_second_order=float(np.max(second)) if second else 0.0,
    )


def geometry_tradeoffs(
    setup: PlannedSetup, tilts_deg: tuple[float, ...] = DEFAULT_TILTS_DEG
) -> tuple[TradeoffRow, ...]:
    """Rows for radius and tilt modes at each tilt, and the vertical wheel (module docstring).

    Everything else (mounting, radius, spin, noise, uncertainties) is the plan's.
    """
    rows = []
    with threadpool_limits(1):  # many small products: BLAS threads only contend
        for geometry in ("radius", "tilt"):
            for tilt in tilts_deg:
                rows.append(tradeoff_row(setup.with_changes(geometry=geometry, tilt_deg=tilt)))
        vertical = setup.with_changes(geometry="vertical", tilt_deg=VERTICAL_TILT_DEG)
        rows.append(tradeoff_row(vertical))
    return tuple(rows)
