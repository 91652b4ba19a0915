"""The joint fit's frozen result: parameters, covariance, residuals, noise, goodness of fit."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint.columns import column_rms
from wheelcal.estimate.joint.gyro_rests import GyroRests
from wheelcal.estimate.joint.identifiability import Identifiability
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.systematic import SystematicBudget
from wheelcal.estimate.joint.twins import TwinChoice
from wheelcal.model import CalibrationParams, ParameterLayout
from wheelcal.recording import SessionInfo


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

    Goodness of fit, as lmfit reports it, from the whitened cost χ² = ‖r̃‖² at the
    result (every stream fitted: the accelerometer's, and the gyro's when it was
    fitted, with the prior on its sensitivity to acceleration), the number of
    whitened residual entries N and of free parameters k (``layout.size``):

    * χ²_ν = χ² / (N − k)  (:attr:`chi2_reduced`; ≈ 1 when the noise model is right),
    * AIC = χ² + 2k         (:attr:`aic`),
    * BIC = χ² + k ln N     (:attr:`bic`),

    each up to the constant −2 ln L − χ² of the fitted noise model (the same for
    two models of one recording and noise model, so differences compare them).

    The noise model is estimated from this fit's own residual, so χ²ᵣ ≈ 1 by
    construction — a model that lacks an effect inflates its noise model instead
    (an imbalanced wheel: χ²ᵣ 0.9994 for the paper's model, 0.9992 with the
    imbalance).  It is not a test of the model: that is the independent noise
    floor (the rests; ``Assessment.noise``) and the closed loop's score tests.
    What the gates made of a fit is not here: a session's
    :class:`~wheelcal.session.result.SessionResult` holds it.
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
    #: The gyroscope's noise model when the gyro was fitted (None otherwise).
    gyro_noise: NoiseModel | None = None
    #: χ² = ‖r̃‖², the whitened cost at the result (NaN when not computed).
    chi2: float = math.nan
    #: N, the whitened residual entries behind :attr:`chi2`.
    entries: int = 0
    #: The gyro's static readings at the rests that the fit used with its stream
    #: (:mod:`~wheelcal.estimate.joint.gyro_rests`; None: none, or no gyro fitted).
    gyro_rests: GyroRests | None = None

    @property
    def dof(self) -> int:
        """N − k: whitened residual entries less free parameters."""
        return self.entries - self.layout.size

    @property
    def chi2_reduced(self) -> float:
        """χ²_ν = χ² / (N − k)."""
        return self.chi2 / self.dof if self.dof > 0 else math.nan

    @property
    def aic(self) -> float:
        """Akaike's criterion χ² + 2k (up to the noise model's constant)."""
        return self.chi2 + 2 * self.layout.size

    @property
    def bic(self) -> float:
        """The Bayesian criterion χ² + k ln N (up to the noise model's constant)."""
        return self.chi2 + self.layout.size * math.log(max(self.entries, 1))

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
