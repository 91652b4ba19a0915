"""Score (Lagrange-multiplier) tests of candidate effects at a fitted model.

For effect parameters θ_e that are zero in the fitted model, the score test
needs only the fit itself: with whitened residual r̃ and Jacobian columns of
the free parameters (b) and of the effect (e),

    H = J̃ᵀJ̃ = [[H_bb, H_be], [H_eb, H_ee]],   g = J̃ᵀ r̃,
    C = H_ee − H_eb H_bb⁻¹ H_be            (information left after the fit),
    u = g_e − H_eb H_bb⁻¹ g_b,
    S = uᵀ C⁻¹ u  ~  χ²(k)  if the effect is absent.

The whitening is the fit's own noise model (AR colour, cross-axis
correlation), so coloured noise does not pose as an effect.  C⁻¹ is also the
Cramér–Rao bound of θ_e at the fit and −C⁻¹u the one-step estimate of its size.

An effect whose C is (nearly) singular — the fit's own parameters can mimic
it — cannot be identified from this recording: it is reported as such and
never tested or fitted into noise.  The fraction of its information left,
λ_min(D⁻½ C D⁻½) with D = diag(H_ee), measures that.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.information import information_fraction, scaled_pinv
from wheelcal.estimate.normal_equations import accumulate
from wheelcal.estimate.result import CalibrationResult
from wheelcal.model import CalibrationParams, ModelOutput
from wheelcal.model.effects import Effect
from wheelcal.model.forward import candidate_columns
from wheelcal.recording import Recording

#: Below this fraction of its own information an effect counts as not identifiable.
IDENTIFIABLE_FRACTION = 1e-4


@dataclass(frozen=True, eq=False)
class ScoreTest:
    """The verdict on one candidate effect."""

    effect: Effect
    statistic: float
    dof: int
    p_value: float
    p_corrected: float
    identifiable: bool
    information_fraction: float
    estimate: np.ndarray  # one-step size of the effect parameters
    predicted_std: np.ndarray  # CRLB of the effect parameters at the fit

    def as_dict(self) -> dict:
        """JSON-ready summary (non-finite numbers as None)."""

        def num(x):
            return float(x) if np.isfinite(x) else None

        names = self.effect.param_names
        return {
            "effect": self.effect.name,
            "label": self.effect.label(),
            "settings": self.effect.settings(),
            "statistic": num(self.statistic),
            "dof": self.dof,
            "p_value": num(self.p_value),
            "p_corrected": num(self.p_corrected),
            "identifiable": self.identifiable,
            "information_fraction": num(self.information_fraction),
            "estimate": dict(zip(names, map(num, self.estimate), strict=True)),
            "predicted_std": dict(zip(names, map(num, self.predicted_std), strict=True)),
        }


def _candidate_columns(layout, candidates):
    """``extra`` callback: ∂v/∂θ_e of every candidate at the current parameters."""

    def extra(params: CalibrationParams, output: ModelOutput, t_s: np.ndarray) -> np.ndarray:
        return np.concatenate(
            [candidate_columns(params, t_s, layout, c, output) for c in candidates]
        )

    return extra


@dataclass(frozen=True, eq=False)
class ScoreContribution:
    """One recording's share of a score test: u (k,), C (k, k) and diag(H_ee) (k,)."""

    effect: Effect
    score: np.ndarray
    information: np.ndarray
    raw_information_diag: np.ndarray


def score_contributions(
    fit: CalibrationResult, recording: Recording, candidates: tuple[Effect, ...]
) -> list[ScoreContribution]:
    """The score u and information C of every candidate not yet in the fit's model."""
    present = {e.name for e in fit.layout.effects}
    candidates = tuple(c for c in candidates if c.name not in present)
    if not candidates:
        return []
    tc = recording.time_s - fit.centre_s
    normal = accumulate(
        fit.params,
        tc,
        recording.accel_mps2,
        fit.layout,
        fit.noise,
        extra=_candidate_columns(fit.layout, candidates),
    )
    size = fit.layout.size
    h, g = normal.hessian, normal.gradient
    h_bb_inv = scaled_pinv(h[:size, :size])
    out = []
    start = size
    for cand in candidates:
        sl = slice(start, start + cand.size)
        start += cand.size
        h_eb = h[sl, :size]
        c = h[sl, sl] - h_eb @ h_bb_inv @ h_eb.T
        u = g[sl] - h_eb @ h_bb_inv @ g[:size]
        out.append(ScoreContribution(cand, u, c, np.diag(h[sl, sl]).copy()))
    return out


def finish_tests(contributions: list[ScoreContribution]) -> list[ScoreTest]:
    """Statistics, p-values and Bonferroni correction from (summed) contributions."""
    from scipy import stats

    results = []
    for part in contributions:
        cand, u, c = part.effect, part.score, part.information
        frac = information_fraction(c, part.raw_information_diag)
        identifiable = frac > IDENTIFIABLE_FRACTION
        if identifiable:
            c_inv = np.linalg.inv(c)
            stat = float(u @ c_inv @ u)
            p = float(stats.chi2.sf(stat, cand.size))
            estimate = -c_inv @ u
            predicted = np.sqrt(np.diag(c_inv))
        else:
            stat, p = np.nan, np.nan
            estimate = np.full(cand.size, np.nan)
            predicted = np.full(cand.size, np.inf)
        results.append(
            ScoreTest(cand, stat, cand.size, p, np.nan, identifiable, frac, estimate, predicted)
        )
    tested = sum(r.identifiable for r in results)
    return [
        dataclasses.replace(r, p_corrected=min(1.0, r.p_value * tested)) if r.identifiable else r
        for r in results
    ]


def score_tests(
    fit: CalibrationResult, recording: Recording, candidates: tuple[Effect, ...]
) -> list[ScoreTest]:
    """Score-test every candidate (not already in the fit's model) at the fit."""
    return finish_tests(score_contributions(fit, recording, candidates))


def pooled_score_tests(
    fits: list[CalibrationResult], recordings: list[Recording], candidates: tuple[Effect, ...]
) -> list[ScoreTest]:
    """One test per candidate of a parameter *shared* by all recordings.

    Under H₀ the per-recording scores are independent with covariances C_k, so
    S = (Σu_k)ᵀ (Σ C_k)⁻¹ (Σu_k) ~ χ²(k) — the candidate's own degrees of
    freedom, not their sum.  Each recording keeps its own bench, spin, offset
    and gain here (the conservative choice: nothing is assumed shared but the
    effect), so the test is valid whatever the other parameters do.
    """
    pooled: dict[str, ScoreContribution] = {}
    order: list[str] = []
    for fit, recording in zip(fits, recordings, strict=True):
        for part in score_contributions(fit, recording, candidates):
            key = part.effect.label()
            if key not in pooled:
                pooled[key] = part
                order.append(key)
            else:
                prev = pooled[key]
                pooled[key] = ScoreContribution(
                    part.effect,
                    prev.score + part.score,
                    prev.information + part.information,
                    prev.raw_information_diag + part.raw_information_diag,
                )
    return finish_tests([pooled[k] for k in order])
