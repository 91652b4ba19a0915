"""Motion parameters in another time origin (the paper's Table I uses the first sample).

The contract reports the spin polynomial of eq. (2) about the window centre;
the paper's Table I gives ϑ₀, ω₀…ω₃ with t = 0 at the first sample (see
:mod:`wheelcal.simulate.presets`).  Moving the origin by Δt is *linear* in the
coefficients: with the phase polynomial ϑ(t) = Σ_k c_k t^k, c = D x where
x = (ϑ₀, ω₀, …, ω_K) and D = diag(1, 1, 1/2, …, 1/(K+1)),

    ϑ'(t') = ϑ(t' + Δt)  ⇒  c'_j = Σ_{k≥j} C(k, j) Δt^(k−j) c_k,

so x' = M x with M = D⁻¹ S D (S the binomial shift).  Errors, the CRLB
covariance (M C Mᵀ) and the truth all map with the same M — so the study can
compare motion parameters in the paper's origin without refitting.
"""

from __future__ import annotations

from math import comb

import numpy as np

from wheelcal.study.montecarlo import MonteCarloSummary


def spin_shift_matrix(degree: int, dt_s: float) -> np.ndarray:
    """M with (ϑ₀', ω₀', …) = M (ϑ₀, ω₀, …) for ϑ'(t') = ϑ(t' + dt_s) (module docstring).

    The same map as :meth:`wheelcal.model.SpinParams.shifted` without its wrap
    of ϑ₀ into (−π, π].
    """
    size = degree + 2
    d = np.diag([1.0, *(1.0 / np.arange(1, size))])
    shift = np.zeros((size, size))
    for j in range(size):
        for k in range(j, size):
            shift[j, k] = comb(k, j) * dt_s ** (k - j)
    return np.linalg.inv(d) @ shift @ d


def spin_indices(names: tuple[str, ...]) -> np.ndarray:
    """Positions of ϑ₀, ω₀…ω_K among reported parameter names (in polynomial order)."""
    idx = [names.index("theta0_rad")]
    k = 0
    while any(n.startswith(f"omega{k}_") for n in names):
        idx.append(next(i for i, n in enumerate(names) if n.startswith(f"omega{k}_")))
        k += 1
    return np.array(idx)


def shift_summary(
    summary: MonteCarloSummary, crlb_covariance: np.ndarray, dt_s: float
) -> tuple[MonteCarloSummary, np.ndarray]:
    """A Monte Carlo summary and its CRLB covariance with the spin origin moved by ``dt_s``.

    ``dt_s = −T/2`` turns centre-time parameters (contract) into first-sample
    ones (paper).  ϑ₀ of the truth is wrapped into (−π, π]; errors are small,
    so they map linearly.  The estimators' own reported σ for the spin block
    would need their full covariance: those entries become NaN.
    """
    idx = spin_indices(summary.names)
    m = spin_shift_matrix(idx.size - 2, dt_s)
    full = np.eye(len(summary.names))
    full[np.ix_(idx, idx)] = m
    truth = full @ summary.truth
    truth[idx[0]] = (truth[idx[0]] + np.pi) % (2 * np.pi) - np.pi
    covariance = full @ crlb_covariance @ full.T
    reported = summary.reported_std.copy()
    reported[:, idx] = np.nan
    shifted = MonteCarloSummary(
        names=summary.names,
        truth=truth,
        crlb_std=np.sqrt(np.diag(covariance)),
        errors=summary.errors @ full.T,
        reported_std=reported,
        failures=summary.failures,
    )
    return shifted, covariance
