"""Systematic budget: what the data cannot see, propagated to the parameters.

The fit holds some quantities fixed at values the user supplies — the radius r
(radius mode), the tilt (tilt / vertical modes), local gravity g — and trusts
the sample clock.  If the assumed value exceeds the true one by δq, the fit
absorbs it: to first order the estimate moves by

    Δx = −(J̃ᵀJ̃)⁻¹ J̃ᵀ (∂ṽ/∂q) δq

(whitened quantities, the same metric as the fit).  A sample-clock scale error
ε reads ω and ω̇ in the wrong seconds but not r ω², which is exactly a relative
radius error of −2ε.  These shifts are common to every recording that shares
the bench and the clock, so repeating the calibration does not average them
away; they are reported separately from the statistical σ.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from wheelcal.estimate.joint.information import scaled_pinv
from wheelcal.model import CalibrationParams, ModelOutput, ParameterLayout, nuisance_sensitivity

#: Spread of local gravity when the session does not give it: 9.780 m/s² at the
#: equator to 9.832 m/s² at the poles, standard gravity in between.
DEFAULT_GRAVITY_STD_MPS2 = 0.02
#: When the session gives local gravity (e.g. from a gravity model): 10 ppm.
GIVEN_GRAVITY_STD_MPS2 = 1e-4
#: Typical crystal tolerance of a microcontroller clock.
DEFAULT_CLOCK_STD_PPM = 100.0


@dataclass(frozen=True, eq=False)
class SystematicSource:
    """One unseen quantity: its assumed σ and the parameter shift per unit of it."""

    name: str
    unit: str
    std: float
    shift_per_unit: (
        np.ndarray
    )  # change of the reported estimates per unit error of the assumed value

    @property
    def shift_std(self) -> np.ndarray:
        """|shift| at one σ of the source."""
        return np.abs(self.shift_per_unit) * self.std


@dataclass(frozen=True, eq=False)
class SystematicBudget:
    """All sources, on the reported parameters (same names as the result)."""

    names: tuple[str, ...]
    sources: tuple[SystematicSource, ...] = field(default=())

    @property
    def total_std(self) -> np.ndarray:
        """Root-sum-square over sources (the sources are independent)."""
        if not self.sources:
            return np.zeros(len(self.names))
        return np.sqrt(sum(s.shift_std**2 for s in self.sources))

    def std_of(self, name: str) -> float:
        """Total systematic σ of one parameter."""
        return float(self.total_std[self.names.index(name)])


def nuisance_columns(layout: ParameterLayout) -> list[str]:
    """The fixed quantities this layout leaves to the systematic budget."""
    names = ["gravity_mps2"]
    if not layout.fit_radius:
        names.insert(0, "radius_m")
    if not layout.fit_tilt:
        names.insert(0, "tilt_rad")
    return names


def nuisance_extra(nuisances: list[str]):
    """``extra`` callback for :func:`~wheelcal.estimate.joint.normal_equations.accumulate`."""

    def extra(params: CalibrationParams, output: ModelOutput, t_s: np.ndarray) -> np.ndarray:
        return np.stack([nuisance_sensitivity(params, t_s, q, output).T for q in nuisances])

    extra.size = len(nuisances)
    return extra


def systematic_budget(
    params: CalibrationParams,
    layout: ParameterLayout,
    hessian: np.ndarray,
    nuisances: list[str],
    report_jacobian: np.ndarray,
    names: tuple[str, ...],
    radius_std_m: float,
    gravity_std_mps2: float,
    clock_std_ppm: float,
    tilt_std_deg: float,
) -> SystematicBudget:
    """Linearised effect of each unseen quantity on the reported parameters.

    ``hessian`` is J̃ᵀJ̃ over [free parameters | nuisance columns] (in the
    order of ``nuisances``), from one accumulation with
    :func:`nuisance_extra`.
    """
    size = layout.size
    inverse = scaled_pinv(hessian[:size, :size])

    def shift(nuisance: str) -> np.ndarray:
        k = size + nuisances.index(nuisance)
        return -(report_jacobian @ (inverse @ hessian[:size, k]))

    sources = [SystematicSource("gravity", "m/s^2", gravity_std_mps2, shift("gravity_mps2"))]
    if "radius_m" in nuisances:
        per_m = shift("radius_m")
        sources.insert(0, SystematicSource("radius", "m", radius_std_m, per_m))
        # A clock whose seconds are (1 + ε) too long ≡ relative radius error −2ε.
        per_ppm = per_m * (-2.0 * params.bench.radius_m * 1e-6)
        sources.append(SystematicSource("sample_clock", "ppm", clock_std_ppm, per_ppm))
    if "tilt_rad" in nuisances:
        per_deg = shift("tilt_rad") * np.deg2rad(1.0)
        sources.insert(0, SystematicSource("tilt", "deg", tilt_std_deg, per_deg))
    return SystematicBudget(names=names, sources=tuple(sources))
