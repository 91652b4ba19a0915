"""Calibration speed: the joint fit against the paper's Nelder–Mead pipeline, one core.

Prints absolute wall times and ratios measured in this same process:

* one 90 s / 200 Hz Table I recording, raw samples → full result (target ≤ 50 ms median);
* the paper's four Nelder–Mead searches on the same data (target: joint ≥ 20× faster);
* how the joint fit's time grows with the number of samples (1×, 10×, 100×).

Run:  python benchmarks/bench_fit.py [--repeats 30] [--skip-100x]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import fmt, times
from wheelcal.estimate.joint import JointFit
from wheelcal.estimate.paper import PaperEstimator
from wheelcal.runtime import tune_allocator
from wheelcal.simulate import simulate, table1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--paper-repeats", type=int, default=3)
    ap.add_argument("--skip-100x", action="store_true", help="skip the 1.8 M-sample case")
    args = ap.parse_args()
    with threadpool_limits(1):
        tune_allocator()  # as the CLI does (see wheelcal.runtime)
        recording = simulate(table1(), np.random.default_rng(0)).recording
        joint = times(lambda: JointFit().fit(recording), args.repeats)
        paper = times(lambda: PaperEstimator().fit(recording), args.paper_repeats)
        print(f"samples: {recording.samples} x 3 axes (90 s at 200 Hz), one BLAS thread")
        print(f"joint ML fit        : {fmt(joint)}")
        print(f"paper Nelder–Mead   : {fmt(paper)}")
        ratio = statistics.median(paper) / statistics.median(joint)
        print(f"speed-up joint/paper: {ratio:8.1f}x   (target >= 20x)")
        print("scaling with samples (same 90 s, higher rate):")
        base = statistics.median(joint)
        for factor in (1, 10, 100):
            if factor == 100 and args.skip_100x:
                continue
            scenario = dataclasses.replace(table1(), rate_hz=200.0 * factor)
            rec = simulate(scenario, np.random.default_rng(1)).recording
            ts = times(lambda rec=rec: JointFit().fit(rec), max(1, args.repeats // factor))
            med = statistics.median(ts)
            print(
                f"  {factor:4d}x {rec.samples:9d} samples: {1e3 * med:9.1f} ms"
                f"   ({med / base:6.1f}x the 1x time, {1e9 * med / rec.samples:7.1f} ns/sample)"
            )


if __name__ == "__main__":
    main()
