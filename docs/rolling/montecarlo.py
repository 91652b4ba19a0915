"""Monte Carlo of rolling-wheel calibration: the figures docs/guide/gyroscope-and-rolling.md quotes (issue 13).

Simulated drives (:func:`wheelcal.simulate.rolling.rolling_scenario`: speed
changes at 0.8–1.5 m/s², a stop, turns up to 0.3 rad/s, 0.5 m/s² road
vibration, a gyro with the default MEMS errors), each calibrated by the whole
session pipeline in geometry ``rolling``; errors in units of the Cramér–Rao
bound at the truth (``tests/test_rolling.py``).  Prints, per parameter group,
the worst |error| / σ_CRLB, the observed spread / σ_CRLB and the reported σ /
observed spread.  Run from the repository root::

    PYTHONPATH=src:tests python docs/rolling/montecarlo.py --seeds 100
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from test_rolling import GROUPS, _group_ratios, _rolling_run


def main() -> None:
    """Run the seeds and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=100)
    parser.add_argument("--save", help="also write the per-run numbers to this JSON file")
    args = parser.parse_args()
    runs = [_rolling_run(seed) for seed in range(args.seeds)]
    if args.save:
        with open(args.save, "w") as f:
            json.dump([[{k: float(v) for k, v in part.items()} for part in run] for run in runs], f)
    honest = _group_ratios(runs)
    print(f"{args.seeds} drives")
    print("| group | worst abs(error)/σ_CRLB | spread/σ_CRLB | reported σ/spread |")
    print("|---|---|---|---|")
    for group, names in GROUPS.items():
        z = np.array([[run[0][n] for n in names] for run in runs])
        spread = np.mean(np.std(z, axis=0, ddof=1))
        print(f"| {group} | {np.max(np.abs(z)):.2f} | {spread:.2f} | {honest[group]:.2f} |")


if __name__ == "__main__":
    main()
