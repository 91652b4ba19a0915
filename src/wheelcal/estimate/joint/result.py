"""The frozen outcome of a calibration: parameters, covariance, residuals, diagnostics."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from wheelcal.estimate.joint.columns import column_rms
from wheelcal.estimate.joint.identifiability import Identifiability
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.systematic import SystematicBudget
from wheelcal.estimate.joint.twins import TwinChoice
from wheelcal.model import CalibrationParams, ParameterLayout
from wheelcal.recording import SessionInfo

if TYPE_CHECKING:
    from wheelcal.session.gates import Assessment


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """What a joint fit returns.

    ``names``/``values``/``covariance`` are the reported parameters (contract
    names: ``tilt_deg``, ``euler_1_deg`` …, ``gain_x`` …, ``offset_x_mps2`` …,
    the spin coefficients and effect parameters).  The covariance is the inverse
    Fisher information of the whitened problem — the noise model (per-axis level,
    colour, cross-axis correlation) is estimated from this recording's residual,
    so σ is honest for the noise actually present.  ∞ marks parameters the
    recording cannot determine.

    ``residual_mps2`` is data − model at ``time_s`` (seconds from
    ``epoch_unix_ns``); the spin's t = 0 is ``centre_s`` on that clock.
    """

    params: CalibrationParams
    layout: ParameterLayout
    names: tuple[str, ...]
    values: np.ndarray
    covariance: np.ndarray
    time_s: np.ndarray
    residual_mps2: np.ndarray
    centre_s: float
    epoch_unix_ns: int
    noise: NoiseModel
    converged: bool
    iterations: int
    warnings: tuple[str, ...]
    systematic: SystematicBudget
    twin: TwinChoice
    identifiability: Identifiability
    info: SessionInfo
    source: str
    topic: str
    notes: tuple[str, ...] = ()
    #: What the plausibility gates made of it (None until assessed).
    assessment: Assessment | None = None
    #: The gyroscope's noise model when the gyro was fitted (None otherwise).
    gyro_noise: NoiseModel | None = None

    @property
    def undetermined(self) -> tuple[str, ...]:
        """Parameters this recording cannot determine (reported as null)."""
        return () if self.assessment is None else self.assessment.undetermined_names

    @property
    def std(self) -> np.ndarray:
        """One-sigma statistical uncertainty per reported parameter."""
        return np.sqrt(np.diag(self.covariance))

    def value_of(self, name: str) -> float:
        """Value of one reported parameter."""
        return float(self.values[self.names.index(name)])

    def std_of(self, name: str) -> float:
        """σ of one reported parameter."""
        return float(self.std[self.names.index(name)])

    def parameters(self) -> dict[str, dict[str, float]]:
        """``{name: {"value", "std"}}`` for every reported parameter (CONTRACT)."""
        return {
            n: {"value": float(v), "std": float(s)}
            for n, v, s in zip(self.names, self.values, self.std, strict=True)
        }

    @property
    def residual_rms_mps2(self) -> np.ndarray:
        """RMS of data − model per axis."""
        return column_rms(self.residual_mps2)

    @property
    def t0_unix_ns(self) -> int:
        """The instant of t = 0 for the spin parameters (CONTRACT ``motion.t0_unix_ns``)."""
        return self.epoch_unix_ns + round(self.centre_s * 1e9)

    @property
    def window_s(self) -> tuple[float, float]:
        """First and last fitted sample time."""
        return float(self.time_s[0]), float(self.time_s[-1])

    @property
    def centred_time_s(self) -> np.ndarray:
        """Sample times about the spin's time origin."""
        return self.time_s - self.centre_s
