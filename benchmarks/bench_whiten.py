"""Whitening a Jacobian under coloured noise: this tree's ``NoiseModel.whiten`` against a revision's.

The joint fit's stage 2 and the motion check whiten every column of J (P × 3 × N)
with the AR filter of each axis and the innovations' L⁻¹.  Times, one BLAS
thread, interleaved round by round, a 22-column Jacobian of 18 000 samples (a
90 s / 200 Hz window) for AR orders 1 … 9 (random stable-ish polynomials, a
correlated innovation covariance), in this tree and at ``--ref``; prints both
medians, the median per-round ratio, and the largest difference between the two
results relative to the largest whitened entry (round-off: ~1e-16).

Run:  python benchmarks/bench_whiten.py --ref 4c9b56f [--repeats 30] [--samples 18000] [--columns 22]
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import interleaved_times
from bench_versus import reference_code

ORDERS = (1, 2, 3, 6, 9)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True, help="git revision to compare with, e.g. 4c9b56f")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--samples", type=int, default=18000, help="per column (a chunk: 32768)")
    ap.add_argument("--columns", type=int, default=22)
    args = ap.parse_args()
    with reference_code(args.ref):
        from wheelcal_ref.estimate.noise_model import NoiseModel as RefNoiseModel

        from wheelcal.estimate.joint.noise_model import NoiseModel
        from wheelcal.runtime import tune_allocator

        rng = np.random.default_rng(0)
        jacobian = rng.normal(size=(args.columns, 3, args.samples))
        residual = rng.normal(size=(args.samples, 3))
        mixing = rng.normal(size=(3, 3))
        cov = mixing @ mixing.T + 3 * np.eye(3)
        print(f"reference {args.ref}; Jacobian {jacobian.shape}, one BLAS thread")
        with threadpool_limits(1):
            tune_allocator()  # as the CLI does
            for order in ORDERS:
                polys = tuple(np.r_[1.0, rng.normal(0, 0.3, order)] for _ in range(3))
                now, ref = NoiseModel(polys, cov), RefNoiseModel(polys, cov)
                ts = interleaved_times(
                    {
                        "ref": lambda m=ref: m.whiten(residual, jacobian),
                        "now": lambda m=now: m.whiten(residual, jacobian),
                    },
                    args.repeats,
                )
                a, b = now.whiten(residual, jacobian)[1], ref.whiten(residual, jacobian)[1]
                ratio = statistics.median(x / y for x, y in zip(ts["ref"], ts["now"], strict=True))
                print(
                    f"  AR({order}): ref {1e3 * statistics.median(ts['ref']):6.2f} ms   "
                    f"now {1e3 * statistics.median(ts['now']):6.2f} ms   ref / now {ratio:5.2f}x   "
                    f"largest difference {np.max(np.abs(a - b)) / np.max(np.abs(b)):.1e}"
                )


if __name__ == "__main__":
    main()
