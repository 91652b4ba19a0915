"""The gyro Monte Carlo figures of docs/guide/gyroscope-and-rolling.md (the slow tests of tests/test_gyro_accuracy.py, printed).

* Table I with a gyro, flexible wheel angle (2 s knots), and with a 0.4 rad/s²
  imbalance (imbalance effect + gyro): spread / CRLB, reported σ / spread, and
  the largest |mean error| / CRLB, per group;
* driven motions through the whole session pipeline with ``--gyro on`` (a
  motor's ±10 % steps, three pushes, 0.5 m/s² vibration): the worst error in
  σ_CRLB over the runs and reported σ / observed spread per group.

    python docs/gyro/montecarlo.py [--runs 100]      # ~20 min on one core
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

import test_gyro_accuracy as mc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=100)
    args = ap.parse_args()
    seeds = range(args.runs)
    with threadpool_limits(1):
        for imbalance in (False, True):
            ratios, bias = mc._monte_carlo_flexible(seeds, imbalance)
            what = "imbalance 0.4 rad/s² + gyro" if imbalance else "gyro + spline (2 s)"
            cells = "; ".join(
                f"{g}: spread/CRLB {s:.2f}, reported/spread {h:.2f}" for g, (s, h) in ratios.items()
            )
            print(f"Table I, {what}, {args.runs} runs: {cells}; max |bias| {bias.max():.2f} σ_CRLB")
        for name, builder in sorted(mc.DRIVEN.items()):
            z, worst = mc._driven_runs(builder, seeds)
            honest = {
                g: float(np.mean(1.0 / np.std(z[:, i], axis=0, ddof=1)))
                for g, i in (("gain", [0, 1, 2]), ("offset", [3, 4, 5]))
            }
            print(
                f"{name}, {args.runs} runs: worst error {worst.max():.2f} σ_CRLB (median "
                f"{np.median(worst):.2f}); reported/spread gains {honest['gain']:.2f}, "
                f"offsets {honest['offset']:.2f}"
            )


if __name__ == "__main__":
    main()
