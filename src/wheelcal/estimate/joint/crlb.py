"""Cramér–Rao bound for any parameter set, sampling plan and Gaussian noise model.

For v = f(x) + n with Gaussian n of known covariance, the Fisher information is
F = Jᵀ Σ⁻¹ J.  With the noise written as per-axis AR processes and correlated
innovations (:class:`~wheelcal.estimate.joint.noise_model.NoiseModel`), Σ⁻¹ factors
as the whitening filter, so F = J̃ᵀ J̃ with J̃ the whitened Jacobian — exact for
white noise and for the simulator's band-limited noise (an AR(2) process),
apart from the first p samples (negligible for N ≫ p).

The bound is evaluated at the truth for tests (never at the fit's own estimate)
and at the estimate for predicted precision in plans and warnings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint.gyro_rests import GyroRests
from wheelcal.estimate.joint.information import covariance_from_fisher, fisher_covariance
from wheelcal.estimate.joint.noise_model import NoiseModel
from wheelcal.estimate.joint.normal_equations import effect_priors
from wheelcal.estimate.joint.reporting import report_transform, transform_covariance
from wheelcal.model import CalibrationParams, ParameterLayout, evaluate


@dataclass(frozen=True, eq=False)
class Bound:
    """Covariance bound on the reported parameters (contract names and units)."""

    names: tuple[str, ...]
    values: np.ndarray
    covariance: np.ndarray
    fisher: np.ndarray  # in optimiser coordinates

    @property
    def std(self) -> np.ndarray:
        """One-sigma bound per reported parameter."""
        return np.sqrt(np.diag(self.covariance))

    def std_of(self, name: str) -> float:
        """One-sigma bound of one named parameter."""
        return float(self.std[self.names.index(name)])

    def as_dict(self) -> dict[str, float]:
        """Map each name to its σ."""
        return dict(zip(self.names, map(float, self.std), strict=True))


def cramer_rao_bound(
    params: CalibrationParams,
    t_s: np.ndarray,
    noise: NoiseModel,
    layout: ParameterLayout | None = None,
) -> Bound:
    """CRLB of the parameters free in ``layout`` at ``params`` for samples at ``t_s``.

    ``t_s`` are centred times (t = 0 at the window centre, as ``params``).
    """
    layout = layout or ParameterLayout(spin_degree=params.spin.degree)
    out = evaluate(params, t_s, layout, jacobian=True)
    _, jw = noise.whiten(np.zeros_like(out.predicted_mps2), out.jacobian)
    prior = effect_priors(params, layout)
    if prior is None:
        cov, fisher = fisher_covariance(jw)
    else:  # the effects' priors add their information (a Bayesian bound)
        flat = jw.reshape(jw.shape[0], -1)
        fisher = flat @ flat.T + np.diag(prior[2])
        cov = covariance_from_fisher(fisher)
    names, values, g = report_transform(params, layout)
    return Bound(names=names, values=values, covariance=transform_covariance(g, cov), fisher=fisher)


def cramer_rao_bound_with_gyro(
    params: CalibrationParams,
    t_s: np.ndarray,
    noise: NoiseModel,
    layout: ParameterLayout,
    gyro_noise: NoiseModel,
    gyro_rests: GyroRests | None = None,
) -> Bound:
    """CRLB when the gyroscope is fitted too: the two streams' informations add.

    ``layout`` holds a :class:`~wheelcal.model.effects.GyroReading` (and
    usually a spline of the wheel angle); ``params`` carry its true values.
    Both streams are sampled at ``t_s``; ``gyro_rests``: the gyro's readings at
    the rests (:class:`~wheelcal.estimate.joint.gyro_rests.GyroRests`), if fitted.
    """
    from wheelcal.estimate.joint.gyro_equations import accumulate_gyro, gyro_prediction
    from wheelcal.estimate.joint.information import covariance_from_fisher
    from wheelcal.estimate.joint.normal_equations import accumulate

    exact = evaluate(params, t_s, layout).predicted_mps2  # zero residual: H = J̃ᵀJ̃
    fisher = accumulate(params, t_s, exact, layout, noise).hessian
    gyro = gyro_prediction(params, t_s, layout)
    rate = accumulate_gyro(params, t_s, gyro, layout, gyro_noise, rests=gyro_rests)
    fisher = fisher + rate.hessian
    names, values, g = report_transform(params, layout)
    cov = transform_covariance(g, covariance_from_fisher(fisher))
    return Bound(names=names, values=values, covariance=cov, fisher=fisher)
