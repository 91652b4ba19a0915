"""Monte Carlo over noise realisations, judged against the Cramér–Rao bound at the truth.

Every accuracy claim of wheelcal is a comparison with the simulator's ground
truth, with the tolerance set by the CRLB *at the truth* (a fit's own σ could be
inflated to pass anything).  :func:`monte_carlo` runs an estimator on
``len(seeds)`` noisy copies of one scenario and reports, per parameter,

* bias / σ_CRLB            (is it unbiased?)
* observed std / σ_CRLB    (is it efficient?)
* reported σ / observed std (is its own uncertainty honest?)

ϑ₀ is compared modulo 2π.  Runs go to worker processes (one BLAS thread each).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np
from threadpoolctl import threadpool_limits

from wheelcal.estimate.crlb import Bound, cramer_rao_bound
from wheelcal.estimate.noise_model import NoiseModel
from wheelcal.estimate.reporting import report_transform
from wheelcal.model import ParameterLayout
from wheelcal.simulate import Scenario, simulate

#: Parameter groups of the paper's Fig. 7–8 (and Table I).
PARAMETER_GROUPS = ("motion", "tilt", "misalignment", "gain", "offset")


def group_of(name: str) -> str:
    """Group of a reported parameter name."""
    if name.startswith(("theta0", "omega")):
        return "motion"
    if name in ("tilt_deg", "radius_m"):
        return "tilt"
    if name.startswith("euler"):
        return "misalignment"
    if name.startswith("gain"):
        return "gain"
    if name.startswith("offset"):
        return "offset"
    return "other"


@dataclass(frozen=True, eq=False)
class MonteCarloSummary:
    """Per-parameter statistics of an estimator over noise realisations."""

    names: tuple[str, ...]
    truth: np.ndarray
    crlb_std: np.ndarray
    errors: np.ndarray  # (runs, P): estimate − truth (ϑ₀ wrapped)
    reported_std: np.ndarray  # (runs, P); NaN when the estimator gives none
    failures: int

    @property
    def runs(self) -> int:
        """Successful runs."""
        return self.errors.shape[0]

    @property
    def bias(self) -> np.ndarray:
        """Mean error per parameter."""
        return self.errors.mean(axis=0)

    @property
    def observed_std(self) -> np.ndarray:
        """Spread of the estimates (ddof = 1)."""
        return self.errors.std(axis=0, ddof=1)

    @property
    def bias_over_crlb(self) -> np.ndarray:
        """Bias in units of σ_CRLB."""
        return self.bias / self.crlb_std

    @property
    def std_over_crlb(self) -> np.ndarray:
        """Efficiency: observed std over σ_CRLB (1 = at the bound)."""
        return self.observed_std / self.crlb_std

    @property
    def reported_over_observed(self) -> np.ndarray:
        """RMS of the reported σ over the observed std (1 = honest)."""
        return np.sqrt(np.mean(self.reported_std**2, axis=0)) / self.observed_std

    def group_mean(self, values: np.ndarray) -> dict[str, float]:
        """Average of a per-parameter quantity over each parameter group."""
        groups = np.array([group_of(n) for n in self.names])
        return {
            g: float(np.mean(values[groups == g])) for g in PARAMETER_GROUPS if np.any(groups == g)
        }

    def table(self) -> list[dict]:
        """One row per parameter, for JSON/CSV."""
        return [
            {
                "parameter": n,
                "group": group_of(n),
                "truth": float(t),
                "crlb_std": float(c),
                "bias": float(b),
                "observed_std": float(s),
                "bias_over_crlb": float(b / c),
                "std_over_crlb": float(s / c),
                "reported_over_observed": float(r),
            }
            for n, t, c, b, s, r in zip(
                self.names,
                self.truth,
                self.crlb_std,
                self.bias,
                self.observed_std,
                self.reported_over_observed,
                strict=True,
            )
        ]


def scenario_bound(scenario: Scenario, layout: ParameterLayout | None = None) -> Bound:
    """CRLB at the scenario's truth for its exact (white or AR) noise."""
    noise = NoiseModel.from_ar(
        scenario.noise.ar_polynomial(scenario.rate_hz),
        scenario.noise.innovation_std(scenario.rate_hz),
    )
    return cramer_rao_bound(scenario.truth, scenario.centred_times_s(), noise, layout)


def _one_run(args) -> tuple[np.ndarray, np.ndarray] | None:
    scenario, estimator, seed = args
    recording = simulate(scenario, np.random.default_rng(seed)).recording
    try:
        result = estimator.fit(recording)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError):
        return None
    std = getattr(result, "std", None)
    layout = getattr(result, "layout", None) or ParameterLayout(
        spin_degree=result.params.spin.degree
    )
    _, values, _ = report_transform(result.params, layout)
    if std is None:
        std = np.full(values.shape, np.nan)
    return values, np.asarray(std)


def monte_carlo(
    scenario: Scenario,
    estimator,
    seeds: Sequence[int],
    workers: int | None = None,
    layout: ParameterLayout | None = None,
) -> MonteCarloSummary:
    """Run ``estimator.fit`` on one noisy recording of ``scenario`` per seed.

    ``estimator`` is any configuration object with ``fit(recording)`` returning
    a result with ``params`` (and optionally ``std`` and ``layout``), e.g.
    :class:`~wheelcal.estimate.joint.JointFit` or
    :class:`~wheelcal.estimate.paper.PaperEstimator`.
    """
    bound = scenario_bound(scenario, layout)
    tasks = [(scenario, estimator, int(s)) for s in seeds]
    workers = workers or min(len(tasks), os.cpu_count() or 1)
    if workers > 1:
        with ProcessPoolExecutor(workers, initializer=_single_thread) as pool:
            outcomes = list(
                pool.map(_one_run, tasks, chunksize=max(1, len(tasks) // (4 * workers)))
            )
    else:
        outcomes = [_one_run(t) for t in tasks]
    ok = [o for o in outcomes if o is not None]
    if not ok:
        raise RuntimeError("every Monte Carlo run failed")
    values = np.array([o[0] for o in ok])
    errors = values - bound.values
    theta = bound.names.index("theta0_rad")
    errors[:, theta] = (errors[:, theta] + np.pi) % (2 * np.pi) - np.pi
    return MonteCarloSummary(
        names=bound.names,
        truth=bound.values,
        crlb_std=bound.std,
        errors=errors,
        reported_std=np.array([o[1] for o in ok]),
        failures=len(outcomes) - len(ok),
    )


def _single_thread() -> None:
    """One BLAS thread per worker process (the workers already use every core)."""
    threadpool_limits(1)
