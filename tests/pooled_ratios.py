"""Monte Carlo fits and pooled, two-sided statistics against an independent CRLB.

Two questions per parameter group G (k parameters, n runs, errors e_j =
estimate − truth, ē their mean, ϑ₀ wrapped):

* **efficiency** — is the spread the Cramér–Rao bound C (tests/independent_bound.py)?
  S = Σ_j (e_j − ē)_Gᵀ C_G⁻¹ (e_j − ē)_G;
* **honesty** — is the spread what the fit reports, Ĉ_j (its covariance)?
  S = Σ_j (e_j − ē)_Gᵀ Ĉ_j,G⁻¹ (e_j − ē)_G.

Whitening by the full k×k block (not parameter by parameter) makes each run's
term χ²_k whatever the correlations between the group's parameters, so the
sum over n runs is χ² with D = k(n − 1) degrees of freedom (one mean per
parameter estimated) — correlated parameters cost no degrees of freedom and
need no conservative guess.  The ratios reported are the group's RMS
"std / σ_CRLB" = √(S_eff/D) and "reported σ / observed spread" = √(D/S_hon):
1 at the bound and for an honest σ.  Under that hypothesis √(χ²_D/D) has the
two-sided acceptance interval of :func:`acceptance`; a sampling scale factor c
on every σ moves the ratio to c, so the interval's half-width is the
deviation the test resolves (≈ z/√(2D): ±8 % for D = 1170 at 99.99 %).
Reported covariances vary a little between runs (each fit estimates its own
noise from ~18 000 residuals per axis, ~0.5 % relative), which the χ² ignores.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy import stats

from wheelcal.estimate.joint.fit import JointFit
from wheelcal.runtime import worker_init
from wheelcal.simulate import simulate


@dataclass(frozen=True, eq=False)
class FitSet:
    """Estimates and reported covariances of n Monte Carlo fits (failed fits counted)."""

    names: tuple[str, ...]
    values: np.ndarray  # (n, P)
    covariances: np.ndarray  # (n, P, P)
    failures: int


def _one_fit(task):
    scenario, seed, fitter = task
    recording = simulate(scenario, np.random.default_rng(seed)).recording
    try:
        result = fitter.fit(recording)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError):
        return None
    return result.names, result.values, result.covariance


def run_joint_fits(scenario, seeds, workers: int | None = None, fitter=None) -> FitSet:
    """Fit one noisy recording of ``scenario`` per seed (default: ``JointFit()``)."""
    fitter = fitter if fitter is not None else JointFit()
    tasks = [(scenario, int(s), fitter) for s in seeds]
    workers = workers or min(2, os.cpu_count() or 1)
    if workers > 1:
        with ProcessPoolExecutor(workers, initializer=worker_init) as pool:
            outcomes = list(pool.map(_one_fit, tasks))
    else:
        outcomes = [_one_fit(t) for t in tasks]
    ok = [o for o in outcomes if o is not None]
    names = ok[0][0]
    assert all(o[0] == names for o in ok)
    return FitSet(
        names=names,
        values=np.array([o[1] for o in ok]),
        covariances=np.array([o[2] for o in ok]),
        failures=len(outcomes) - len(ok),
    )


def errors_against(fits: FitSet, truth: np.ndarray) -> np.ndarray:
    """estimate − truth (n, P), ϑ₀ wrapped into (−π, π]."""
    errors = fits.values - truth
    theta = fits.names.index("theta0_rad")
    errors[:, theta] = (errors[:, theta] + np.pi) % (2 * np.pi) - np.pi
    return errors


@dataclass(frozen=True)
class Pooled:
    """χ² sums of one group (see the module docstring) and their degrees of freedom."""

    efficiency_chi2: float
    honesty_chi2: float
    dof: int

    def __add__(self, other: Pooled) -> Pooled:
        return Pooled(
            self.efficiency_chi2 + other.efficiency_chi2,
            self.honesty_chi2 + other.honesty_chi2,
            self.dof + other.dof,
        )

    @property
    def std_over_crlb(self) -> float:
        """RMS spread over σ_CRLB in whitened directions."""
        return float(np.sqrt(self.efficiency_chi2 / self.dof))

    @property
    def reported_over_observed(self) -> float:
        """RMS reported σ over the observed spread in whitened directions."""
        return float(np.sqrt(self.dof / self.honesty_chi2))


def pooled(errors: np.ndarray, bound_cov: np.ndarray, reported: np.ndarray, idx) -> Pooled:
    """χ² of the group ``idx`` against the bound's and each run's reported covariance."""
    idx = np.asarray(idx)
    centred = errors[:, idx] - errors[:, idx].mean(axis=0)
    bound_inv = np.linalg.inv(bound_cov[np.ix_(idx, idx)])
    eff = float(np.einsum("ni,ij,nj->", centred, bound_inv, centred))
    hon = 0.0
    for e, cov in zip(centred, reported, strict=True):
        hon += float(e @ np.linalg.solve(cov[np.ix_(idx, idx)], e))
    n, k = centred.shape
    return Pooled(eff, hon, k * (n - 1))


def acceptance(dof: int, alpha: float) -> tuple[float, float]:
    """Two-sided interval of √(χ²_dof / dof) with probability 1 − alpha."""
    lo, hi = stats.chi2.ppf([alpha / 2, 1 - alpha / 2], dof)
    return float(np.sqrt(lo / dof)), float(np.sqrt(hi / dof))
