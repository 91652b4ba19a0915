"""Monte Carlo over noise realisations, judged against the Cramér–Rao bound at the truth.

Every accuracy claim of wheelcal is a comparison with the simulator's ground
truth, with the tolerance set by the CRLB *at the truth* (a fit's own σ could be
inflated to pass anything).  :func:`monte_carlo` runs an estimator on
``len(seeds)`` noisy copies of one scenario and reports, per parameter,

* bias / σ_CRLB            (is it unbiased?)
* observed std / σ_CRLB    (is it efficient?)
* reported σ / observed std (is its own uncertainty honest?)

ϑ₀ is compared modulo 2π.  Runs go to worker processes (one BLAS thread each).

Larger studies (:mod:`wheelcal.study.runner`) mix many scenarios and
estimators in one process pool with :func:`run_fits` and turn each group of
outcomes into a summary with :func:`summarise`; :func:`monte_carlo` is the
one-scenario case of the same two steps.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from wheelcal.estimate.joint import Bound, NoiseModel, cramer_rao_bound, report_transform
from wheelcal.model import ParameterLayout
from wheelcal.runtime import worker_init
from wheelcal.simulate import Scenario, simulate

#: One Monte Carlo fit: simulate ``scenario`` with ``seed``, fit with ``estimator``.
FitTask = tuple[Scenario, object, int]
#: Outcome of one fit: reported values and σ (NaN when not given), or ``None`` if it failed.
FitOutcome = tuple[np.ndarray, np.ndarray] | None
#: Progress callback: (fits done, fits in total).
FitProgress = Callable[[int, int], None]

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


def group_means(names: Sequence[str], values: np.ndarray) -> dict[str, float]:
    """Average of a per-parameter quantity (in ``names`` order) over each group present."""
    groups = np.array([group_of(n) for n in names])
    return {g: float(np.mean(values[groups == g])) for g in PARAMETER_GROUPS if np.any(groups == g)}


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
        return group_means(self.names, values)

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
    progress: FitProgress | None = None,
) -> MonteCarloSummary:
    """Run ``estimator.fit`` on one noisy recording of ``scenario`` per seed.

    ``estimator`` is any configuration object with ``fit(recording)`` returning
    a result with ``params`` (and optionally ``std`` and ``layout``), e.g.
    :class:`~wheelcal.estimate.joint.fit.JointFit` or
    :class:`~wheelcal.estimate.paper.estimator.PaperEstimator`.  ``progress`` (optional)
    is called with (fits done, fits in total) as fits finish.
    """
    bound = scenario_bound(scenario, layout)
    tasks = [(scenario, estimator, int(s)) for s in seeds]
    return summarise(bound, run_fits(tasks, workers, progress))


def run_fits(
    tasks: Sequence[FitTask],
    workers: int | None = None,
    progress: FitProgress | None = None,
) -> list[FitOutcome]:
    """Run many (scenario, estimator, seed) fits, in worker processes when ``workers`` > 1.

    Returns the outcomes in the order of ``tasks`` (``None`` for a failed fit).
    ``workers`` defaults to every core; each worker uses one BLAS thread.
    Tasks are handed out one at a time, so put the slowest first for the best
    load balance.
    """
    tasks = list(tasks)
    outcomes: list[FitOutcome] = [None] * len(tasks)
    workers = workers or min(len(tasks), os.cpu_count() or 1)
    if workers > 1 and len(tasks) > 1:
        with ProcessPoolExecutor(workers, initializer=worker_init) as pool:
            futures = {pool.submit(_one_run, task): i for i, task in enumerate(tasks)}
            for done, future in enumerate(as_completed(futures), start=1):
                outcomes[futures[future]] = future.result()
                if progress is not None:
                    progress(done, len(tasks))
    else:
        for i, task in enumerate(tasks):
            outcomes[i] = _one_run(task)
            if progress is not None:
                progress(i + 1, len(tasks))
    return outcomes


def summarise(bound: Bound, outcomes: Sequence[FitOutcome]) -> MonteCarloSummary:
    """Errors against the truth of ``bound`` (ϑ₀ wrapped into (−π, π]) and failure count."""
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
