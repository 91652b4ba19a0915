"""Speed of the field-recording simulator (wheelcal.simulate.field), one core.

Prints absolute times, and ratios against a baseline measured in the same
process, round by round (interleaved):

* a 2-minute 120 Hz car drive (14 401 samples, gyro, road vibration) — target
  well under a second (the second rolling simulator it was once measured
  against, ``wheelcal.simulate.rolling``, is gone: issue 41 item 6);
* a 400 Hz wheelchair coast (~30 s, ~12 000 samples);
* a 90 s bench spin at 200 Hz, against the paper-model session simulator
  (:func:`wheelcal.simulate.session.simulate_session`, Table II) as the baseline.

Each time includes drawing the scenario (the profile) and recording it.

Run:  python benchmarks/bench_field_simulator.py [--repeats 15]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import fmt, interleaved_times
from wheelcal.simulate.field import bench_spin, car_drive, simulate_field, wheelchair_coast
from wheelcal.simulate.gyro import GyroSpec
from wheelcal.simulate.presets import table2
from wheelcal.simulate.session import simulate_session


def _field(profile, seed: int = 1, **options):
    def run():
        rng = np.random.default_rng(seed)
        return simulate_field(profile(rng, **options), rng)

    return run


def _baseline_session():
    rng = np.random.default_rng(1)
    scenario = table2(rng=rng)
    return simulate_session(dataclasses.replace(scenario, gyro=GyroSpec()), rng)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    runs = {
        "car drive 120 s, 120 Hz": _field(car_drive),
        "wheelchair coast, 400 Hz": _field(wheelchair_coast),
        "bench spin 90 s, 200 Hz": _field(bench_spin, free_spin_s=90.0),
        "baseline: simulate_session 90 s, 200 Hz": _baseline_session,
    }
    samples = {name: fn().recording.samples for name, fn in runs.items()}
    with threadpool_limits(1):
        times = interleaved_times(runs, args.repeats)
    for name, ts in times.items():
        print(f"{name:42s} {samples[name]:6d} samples  {fmt(ts)}")
    for ours, base in (("bench spin 90 s, 200 Hz", "baseline: simulate_session 90 s, 200 Hz"),):
        ratio = statistics.median(a / b for a, b in zip(times[ours], times[base], strict=True))
        print(f"ratio {ours} / {base}: {ratio:.2f} (median of per-round ratios)")


if __name__ == "__main__":
    main()
