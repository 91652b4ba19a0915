"""Gyro-aided calibration speed against the accelerometer-only fit, one core.

Prints absolute times and ratios measured in this same process, on whole
simulated sessions (90 s of motion at 200 Hz with a gyroscope, rest, push and
stop around it), through :class:`~wheelcal.estimate.session_fit.SessionFit`:

* a clean free spin: accelerometer only (``--gyro off``) against the gyro-aided
  fit forced on (``--gyro on``: spline wheel angle with knots chosen by BIC,
  gyro stream, disturbance trimming) — target ≤ 3×;
* a wheel pushed three times: ``--gyro on`` (the accelerometer alone can only use
  the stretch between two pushes).

Run:  python benchmarks/bench_gyro.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import fmt, interleaved_times, times
from wheelcal.estimate.session_fit import SessionFit
from wheelcal.runtime import tune_allocator
from wheelcal.simulate import hostile
from wheelcal.simulate.gyro import GyroSpec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    with threadpool_limits(1):
        tune_allocator()
        clean = hostile.clean(np.random.default_rng(1), gyro=GyroSpec()).recording
        pushes = hostile.three_pushes(np.random.default_rng(9), gyro=GyroSpec()).recording
        pair = interleaved_times(
            {
                "acc": lambda: SessionFit(gyro="off").run(clean),
                "gyro": lambda: SessionFit(gyro="on").run(clean),
            },
            args.repeats,
        )
        acc, gyro = pair["acc"], pair["gyro"]
        pushed = times(lambda: SessionFit(gyro="on").run(pushes), max(3, args.repeats // 2))
    print(f"session of {clean.samples} samples (90 s spin at 200 Hz + rest, push, stop), one core")
    print(f"clean spin, accelerometer only : {fmt(acc)}")
    print(f"clean spin, gyro-aided (on)    : {fmt(gyro)}")
    print(f"three pushes, gyro-aided (on)  : {fmt(pushed)}")
    ratio = statistics.median(gyro) / statistics.median(acc)
    paired = statistics.median(g / a for g, a in zip(gyro, acc, strict=True))
    print(f"gyro-aided / accelerometer-only (clean spin): {ratio:.2f}x  (target <= 3x)")
    print(f"  median of the per-round ratios (runs interleaved): {paired:.2f}x")


if __name__ == "__main__":
    main()
