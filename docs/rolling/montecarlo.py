"""Monte Carlo of ``--geometry rolling``: the figures docs/guide/gyroscope-and-rolling.md quotes.

Simulated car drives from the field simulator (:func:`wheelcal.simulate.car_drive`:
two minutes at 120 Hz, speed changes, turns, stops, a road, a factory IMU's gyro)
on a vertical wheel (camber 0) on a level road with the sensor's radius in the file, each
calibrated with ``geometry="rolling"`` — the field fit asked for by name, the
radius held; errors in units of the Cramér–Rao bound at the truth
(``tests/test_rolling.py``, whose slow test runs seeds 100–139).  Prints, per
parameter group, the worst |error| / σ_CRLB, the observed spread / σ_CRLB and
the reported σ / observed spread.  Run from the repository root::

    PYTHONPATH=src:tests python docs/rolling/montecarlo.py --seeds 40
"""

from __future__ import annotations

import argparse

from threadpoolctl import threadpool_limits

from test_rolling import _study_run, study_table


def main() -> None:
    """Run the seeds and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=40)
    args = parser.parse_args()
    with threadpool_limits(1):
        runs = [_study_run(100 + seed) for seed in range(args.seeds)]
    refused = [run for run in runs if isinstance(run, str)]
    print(f"{args.seeds} drives, {len(refused)} refused ({', '.join(refused) or 'none'})")
    print("| group | worst abs(error)/σ_CRLB | spread/σ_CRLB | reported σ/spread |")
    print("|---|---|---|---|")
    for group, (worst, spread, honest) in study_table(runs).items():
        print(f"| {group} | {worst:.2f} | {spread:.2f} | {honest:.2f} |")


if __name__ == "__main__":
    main()
