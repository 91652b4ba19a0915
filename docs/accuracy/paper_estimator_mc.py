"""Measure the paper's four-step estimator against the Cramér–Rao bound at the truth.

The four-step estimator (paper Sec. III) is not efficient: its step A picks the
realignment T'' by an extreme-value statistic of the noise (eq. 26), and every
later step inherits that error.  This script measures by how much, on Table I at
σ_n = 0.08 m/s²: for ``--runs`` noise draws (seeds from ``--first-seed``) it fits
each recording with :class:`~wheelcal.estimate.paper.estimator.PaperEstimator` and prints,
per parameter, the observed std over σ_CRLB at the truth (the inefficiency
factor F that ``tests/test_paper_estimator.py`` states in ``PAPER_OVER_CRLB``),
the bias over σ_CRLB, and the bias's t statistic, bias / (std/√n).

Run:  python docs/accuracy/paper_estimator_mc.py [--runs 200] [--workers 2]
      (about 1 s per fit)
"""

from __future__ import annotations

import argparse

import numpy as np

from wheelcal.estimate.paper.estimator import PaperEstimator
from wheelcal.simulate import table1
from wheelcal.study import monte_carlo


def paper_monte_carlo(seeds, workers: int | None = None):
    """MonteCarloSummary of the paper's estimator on Table I (σ_n = 0.08 m/s²)."""
    return monte_carlo(table1(), PaperEstimator(), seeds, workers=workers)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--first-seed", type=int, default=30000)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    s = paper_monte_carlo(range(args.first_seed, args.first_seed + args.runs), args.workers)
    n = s.runs
    print(f"Table I, σ_n = 0.08 m/s², paper's estimator: n = {n}, failures = {s.failures}")
    print(f"relative SE of a std from n runs: {1 / np.sqrt(2 * (n - 1)):.3f}")
    print(f"{'parameter':<16}{'std/σ_CRLB':>12}{'bias/σ_CRLB':>13}{'t':>8}")
    t = s.bias / (s.observed_std / np.sqrt(n))
    for name, f, b, tt in zip(s.names, s.std_over_crlb, s.bias_over_crlb, t, strict=True):
        print(f"{name:<16}{f:>12.2f}{b:>13.2f}{tt:>8.2f}")


if __name__ == "__main__":
    main()
