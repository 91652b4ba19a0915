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
from scipy import special

from wheelcal.estimate.fisher_quadrature import quadrature_rows, stride_for
from wheelcal.estimate.information import information_fraction, scaled_pinv
from wheelcal.estimate.normal_equations import (
    CHUNK_SAMPLES,
    accumulate,
    quadrature_hessian,
    whitened_back,
)
from wheelcal.estimate.result import CalibrationResult
from wheelcal.model import CalibrationParams, ModelOutput, evaluate
from wheelcal.model.effects import Effect
from wheelcal.model.forward import (
    EvaluatedModel,
    candidate_columns,
    jacobian_transpose_times,
    spin_adjoint,
)
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
    fit: CalibrationResult,
    recording: Recording,
    candidates: tuple[Effect, ...],
    evaluated: EvaluatedModel | None = None,
) -> list[ScoreContribution]:
    """The score u and information C of every candidate not yet in the fit's model.

    For the paper's model H comes by quadrature and g from every sample without a
    Jacobian (:func:`_normal_by_quadrature`); otherwise both are summed over every
    sample.  ``evaluated``: the model at the fit as its last pass left it.
    """
    present = {e.name for e in fit.layout.effects}
    candidates = tuple(c for c in candidates if c.name not in present)
    if not candidates:
        return []
    tc = recording.time_s - fit.centre_s
    size = fit.layout.size
    stride = 1 if fit.layout.effects else stride_for(tc, fit.params.spin, fit.noise.order)
    if stride > 1:
        h, g = _normal_by_quadrature(fit, recording, candidates, stride, evaluated)
    else:
        normal = accumulate(
            fit.params,
            tc,
            recording.accel_mps2,
            fit.layout,
            fit.noise,
            extra=_candidate_columns(fit.layout, candidates),
        )
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


def _lean_columns(candidates: tuple[Effect, ...], layout):
    """``extra`` callback of the candidates' columns, per-axis effects filled leanly."""

    def extra(params: CalibrationParams, output: ModelOutput, t_s: np.ndarray) -> np.ndarray:
        total = sum(c.size for c in candidates)
        cols = np.zeros((total, 3, t_s.size))
        row = 0
        for cand in candidates:
            lean = _axis_columns(cand, params, output, t_s)
            if lean is None:
                cols[row : row + cand.size] = candidate_columns(params, t_s, layout, cand, output)
            else:
                values, axes = lean
                for k, axis in enumerate(axes):
                    cols[row + k, axis] = values[k]
            row += cand.size
        return cols

    extra.size = sum(c.size for c in candidates)
    return extra


def _axis_columns(cand: Effect, params: CalibrationParams, output: ModelOutput, t_s):
    lean = getattr(cand, "axis_columns", None)
    if lean is None:
        return None
    return lean(t_s, output.sensed_mps2, params.sensor.gain)


def _normal_by_quadrature(
    fit: CalibrationResult,
    recording: Recording,
    candidates: tuple[Effect, ...],
    stride: int,
    evaluated: EvaluatedModel | None,
) -> tuple[np.ndarray, np.ndarray]:
    """H over [the fit's parameters | the candidates] by quadrature, g over every sample.

    H sums smooth functions of time (:mod:`~wheelcal.estimate.fisher_quadrature`);
    g = J̃ᵀr̃ is a sum of noise, taken over every sample without a Jacobian: the
    residual whitened back (u = WᵀW r), the fit's parameters by the model's reverse
    mode, a sensor candidate as Σ (its column on its axis) · u, a spin candidate
    through the wheel angle's adjoint rows (:func:`~wheelcal.model.forward.spin_adjoint`).
    """
    params, layout, noise = fit.params, fit.layout, fit.noise
    tc = recording.time_s - fit.centre_s
    size = layout.size
    extra = _lean_columns(candidates, layout)
    rows = quadrature_rows(tc.size, noise.order, stride)
    hess = quadrature_hessian(params, tc, layout, noise, rows, extra)
    grad = np.zeros(size + extra.size)
    p = noise.order
    for start in range(0, tc.size, CHUNK_SAMPLES):
        stop = min(tc.size, start + CHUNK_SAMPLES)
        lo = max(0, start - p)
        t = tc[lo:stop]
        output = evaluated.output_at(params, t) if evaluated is not None else None
        if output is None:
            output = evaluate(params, t, layout)
        _, u = whitened_back(output.predicted_mps2 - recording.accel_mps2[lo:stop], noise)
        grad[:size] += jacobian_transpose_times(params, t, layout, u, output)
        adjoint = None
        row = size
        for cand in candidates:
            lean = _axis_columns(cand, params, output, t)
            if lean is not None:
                values, axes = lean
                for k, axis in enumerate(axes):
                    grad[row + k] += values[k] @ u[axis]
            elif cand.stage == "spin":
                if adjoint is None:
                    adjoint = spin_adjoint(params, u, output)
                force = output.force
                rows = cand.own_rows(t, output.kinematics, force.sin_theta, force.cos_theta)
                grad[row : row + cand.size] += sum(
                    r @ a for r, a in zip(rows, adjoint, strict=True)
                )
            else:
                cols = candidate_columns(params, t, layout, cand, output)
                grad[row : row + cand.size] += cols.reshape(cand.size, -1) @ u.reshape(-1)
            row += cand.size
    return hess, grad


def finish_tests(contributions: list[ScoreContribution]) -> list[ScoreTest]:
    """Statistics, p-values and Bonferroni correction from (summed) contributions."""
    results = []
    for part in contributions:
        cand, u, c = part.effect, part.score, part.information
        frac = information_fraction(c, part.raw_information_diag)
        identifiable = frac > IDENTIFIABLE_FRACTION
        if identifiable:
            c_inv = np.linalg.inv(c)
            stat = float(u @ c_inv @ u)
            # The χ² survival function (what stats.chi2.sf returns, without its ~40 µs of checks).
            p = float(special.chdtrc(cand.size, stat))
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
    fit: CalibrationResult,
    recording: Recording,
    candidates: tuple[Effect, ...],
    evaluated: EvaluatedModel | None = None,
) -> list[ScoreTest]:
    """Score-test every candidate (not already in the fit's model) at the fit."""
    return finish_tests(score_contributions(fit, recording, candidates, evaluated))


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
