"""Statistics of one estimator at one noise level, as the paper's Fig. 7–8 and Table I show them.

For each parameter with true value v_true, over the runs at one σ_n:

* **normalised deviation** (Fig. 7): 100 (μ / v_true − 1) %, μ the mean estimate;
* **normalised σ** (Fig. 8): σ / |v_true|, except gains and offsets, which the
  paper normalises by 1 (footnote 1: "μ_o = μ_γ = 1"), i.e. plain σ (offsets in m/s²);

both averaged over the paper's groups (offset, gain, tilt, misalignment,
motion).  The CRLB is normalised the same way, so it shares Fig. 8's axes.
Motion parameters are taken in the paper's origin (first sample, see
:mod:`wheelcal.study.origin`): in centre time ω₁…ω₃ have other true values and
the normalised numbers would not be comparable with the paper's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wheelcal.study.montecarlo import MonteCarloSummary, group_means, group_of
from wheelcal.study.origin import shift_summary

#: Groups normalised by 1 instead of |v_true| (paper, footnote 1 of Fig. 8).
UNIT_NORMALISED_GROUPS = ("gain", "offset")
#: 1.4826 MAD estimates σ for Gaussian data; compared with the std it flags heavy tails.
_MAD_TO_SIGMA = 1.482602218505602


@dataclass(frozen=True, eq=False)
class LevelStats:
    """One estimator at one noise level (motion parameters in the paper's origin).

    Attributes
    ----------
    errors:
        (runs, P) estimate − truth of every successful run.
    crlb_std:
        Cramér–Rao bound at the truth, in the same origin.
    """

    estimator: str
    sigma_mps2: float
    names: tuple[str, ...]
    truth: np.ndarray
    errors: np.ndarray
    crlb_std: np.ndarray
    failures: int

    @property
    def runs(self) -> int:
        """Successful runs."""
        return self.errors.shape[0]

    @property
    def groups(self) -> tuple[str, ...]:
        """Group of each parameter."""
        return tuple(group_of(n) for n in self.names)

    @property
    def bias(self) -> np.ndarray:
        """Mean error μ − v_true."""
        return self.errors.mean(axis=0)

    @property
    def mean(self) -> np.ndarray:
        """Mean estimate μ."""
        return self.truth + self.bias

    @property
    def std(self) -> np.ndarray:
        """Spread of the estimates (ddof = 1)."""
        return self.errors.std(axis=0, ddof=1)

    @property
    def bias_se(self) -> np.ndarray:
        """Standard error of the mean, σ / √n."""
        return self.std / np.sqrt(self.runs)

    @property
    def robust_std(self) -> np.ndarray:
        """1.4826 × median absolute deviation (≈ std for Gaussian spread)."""
        dev = self.errors - np.median(self.errors, axis=0)
        return _MAD_TO_SIGMA * np.median(np.abs(dev), axis=0)

    @property
    def normaliser(self) -> np.ndarray:
        """|v_true|, or 1 for gains and offsets (paper, Fig. 8 footnote)."""
        unit = np.array([g in UNIT_NORMALISED_GROUPS for g in self.groups])
        return np.where(unit, 1.0, np.abs(self.truth))

    @property
    def normalised_deviation_pct(self) -> np.ndarray:
        """Fig. 7: 100 (μ / v_true − 1) %."""
        return 100.0 * self.bias / self.truth

    @property
    def normalised_std(self) -> np.ndarray:
        """Fig. 8: σ / μ-normaliser."""
        return self.std / self.normaliser

    @property
    def crlb_normalised_std(self) -> np.ndarray:
        """The CRLB on Fig. 8's axes."""
        return self.crlb_std / self.normaliser

    @property
    def std_over_crlb(self) -> np.ndarray:
        """Efficiency: σ / σ_CRLB (1 = at the bound)."""
        return self.std / self.crlb_std

    def group_mean(self, values: np.ndarray) -> dict[str, float]:
        """Average over each of the paper's groups (as in Fig. 7–8)."""
        return group_means(self.names, values)

    def value(self, quantity: str, name: str) -> float:
        """One entry of a per-parameter property, e.g. ``value("std", "gain_x")``."""
        return float(getattr(self, quantity)[self.names.index(name)])


def level_stats(
    estimator: str,
    sigma_mps2: float,
    summary: MonteCarloSummary,
    crlb_covariance: np.ndarray,
    duration_s: float,
) -> LevelStats:
    """Statistics of a centre-time Monte Carlo summary, motion moved to the first sample."""
    shifted, _ = shift_summary(summary, crlb_covariance, -0.5 * duration_s)
    return LevelStats(
        estimator=estimator,
        sigma_mps2=float(sigma_mps2),
        names=shifted.names,
        truth=shifted.truth,
        errors=shifted.errors,
        crlb_std=shifted.crlb_std,
        failures=shifted.failures,
    )


def proportionality_slope(levels: list[LevelStats], group: str) -> float:
    """Slope of log(group-mean normalised σ) against log σ_n (1 = σ ∝ σ_n, Fig. 8)."""
    x = np.log([s.sigma_mps2 for s in levels])
    y = np.log([s.group_mean(s.normalised_std)[group] for s in levels])
    return float(np.polyfit(x, y, 1)[0])
