"""Print the Monte Carlo figures for `wheelcal plan` (predicted σ vs joint-fit spread; docs/guide/planning.md).

For the four setups of ``tests/test_plan_montecarlo.py`` (paper bench, paper bench
with the recommended mounting, tilt mode with low-pass noise, vertical wheel) the
plan is simulated ``--runs`` times and fitted by the plan's JointFit (the same
code as the slow test).  Printed per setup: observed spread / predicted σ
(min, max, mean over the parameters) and the fit's reported σ / observed spread;
then the worst offset σ of the paper bench over that of the recommended
mounting, predicted and observed.

Run:  python docs/plan/montecarlo.py [--runs 300]   (300 runs: a few minutes on 2 cores)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from test_plan_montecarlo import NAMES, _compare, setups

OFFSETS = ("offset_x_mps2", "offset_y_mps2", "offset_z_mps2")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=300)
    args = parser.parse_args()
    worst = {}
    for name in NAMES:
        predicted, expected, summary = _compare(setups(full=True)[name], args.runs, 20000)
        ratio = summary.observed_std / expected
        honest = summary.reported_over_observed
        se = 1 / np.sqrt(2 * (summary.runs - 1))
        print(
            f"{name:<20} n = {summary.runs}  observed/predicted σ: {ratio.min():.3f}–"
            f"{ratio.max():.3f} (mean {ratio.mean():.3f}; max |ratio − 1| = "
            f"{np.max(np.abs(ratio - 1)):.3f}, 4 SE = {4 * se:.3f})  reported/observed: "
            f"{honest.min():.3f}–{honest.max():.3f}"
        )
        idx = [summary.names.index(n) for n in OFFSETS]
        worst[name] = (np.max(predicted.std[idx]), np.max(summary.observed_std[idx]))
    (p0, o0), (p1, o1) = worst["paper-radius"], worst["paper-best-mounting"]
    print(
        f"worst offset σ, paper mounting / recommended mounting: predicted {p0 / p1:.2f}×, "
        f"Monte Carlo {o0 / o1:.2f}×"
    )


if __name__ == "__main__":
    main()
