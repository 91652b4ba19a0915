"""What freeing a part of the model would change: the result of a score and Hausman test.

The motion check frees the wheel angle (:mod:`wheelcal.session.motion_check`), the
lean check the camber (:mod:`wheelcal.estimate.field.lean_check`).  Both report, at
the fit, the score statistic of the freed spline's coefficients and the shift Δ of
each checked parameter in two scales: against the fit's σ (material?) and against
its own σ, √(σ²_free − σ²_fit) (significant?).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar


@dataclass(frozen=True)
class FreedCheck:
    """The score test of a freed spline and the shifts it makes (see the module docstring)."""

    #: What is freed, for the JSON's ``alternative``.
    ALTERNATIVE: ClassVar[str] = "a cubic B-spline correction"

    statistic: float  # score χ² of the spline coefficients
    dof: int
    p_value: float
    shift_sigma: dict[str, float]  # |Δ| / σ of the fit, per checked parameter
    shift_z: dict[str, float]  # |Δ| / √(σ²_free − σ²_fit)
    spacing_s: float

    def moved(self, z_limit: float, material_sigma: float) -> tuple[str, ...]:
        """The parameters that move significantly and materially."""
        return tuple(
            n
            for n in self.shift_z
            if self.shift_z[n] > z_limit and self.shift_sigma[n] > material_sigma
        )

    def to_dict(self) -> dict:
        """For the calibration JSON."""
        return {
            "alternative": self.ALTERNATIVE,
            "knot_spacing_s": self.spacing_s,
            "statistic": self.statistic,
            "dof": self.dof,
            "p_value": self.p_value,
            "shift_sigma": self.shift_sigma,
            "shift_z": self.shift_z,
        }
