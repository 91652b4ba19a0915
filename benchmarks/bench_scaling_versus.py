"""Time against samples, this tree against an earlier revision, interleaved in one process.

The same 90 s Table I recording at 200 Hz × ``--factors`` (1×, 10×, 100×: 18 k, 180 k,
1.8 M samples), one BLAS thread.  For each size, the joint fit (``JointFit().fit``)
and the whole calibration (``SessionFit().run``) of ``--ref`` (extracted as
``wheelcal_ref``, see ``bench_versus.py``) and of this tree run in turn, round by
round; prints both medians, the median of the per-round ratios, each version's
growth against its own 1× time, and the largest change of a gain or offset between
the two (in this tree's σ) with the AR order each fit chose.

Run:  python benchmarks/bench_scaling_versus.py --ref main [--factors 1 10 100] [--repeats 10]
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import interleaved_times
from bench_versus import reference_code


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True, help="git revision to compare with")
    ap.add_argument("--factors", type=int, nargs="+", default=[1, 10, 100])
    ap.add_argument("--repeats", type=int, default=10, help="rounds at 1× (÷ factor, ≥ 1)")
    args = ap.parse_args()
    with reference_code(args.ref):
        from wheelcal_ref.estimate.joint import JointFit as RefJoint
        from wheelcal_ref.estimate.session_fit import SessionFit as RefSession

        from wheelcal.estimate.joint.fit import JointFit
        from wheelcal.runtime import tune_allocator
        from wheelcal.session.fit import SessionFit
        from wheelcal.simulate import simulate, table1

        with threadpool_limits(1):
            tune_allocator()
            base: dict[str, float] = {}
            print(f"reference {args.ref}; one BLAS thread; ms (median), ratio ref/now per round")
            for factor in args.factors:
                scenario = dataclasses.replace(table1(), rate_hz=200.0 * factor)
                rec = simulate(scenario, np.random.default_rng(1)).recording
                ts = interleaved_times(
                    {
                        "joint ref": lambda r=rec: RefJoint().fit(r),
                        "joint now": lambda r=rec: JointFit().fit(r),
                        "session ref": lambda r=rec: RefSession().run(r),
                        "session now": lambda r=rec: SessionFit().run(r),
                    },
                    max(1, args.repeats // factor),
                )
                for what in ("joint", "session"):
                    ref, now = ts[f"{what} ref"], ts[f"{what} now"]
                    ratios = [a / b for a, b in zip(ref, now, strict=True)]
                    med_ref, med_now = statistics.median(ref), statistics.median(now)
                    if factor == args.factors[0]:
                        base[f"{what} ref"], base[f"{what} now"] = med_ref, med_now
                    print(
                        f"{factor:4d}x {what:7s} {rec.samples:9d} samples: ref {1e3 * med_ref:9.1f}"
                        f" ms ({med_ref / base[f'{what} ref']:6.1f}x its first), now"
                        f" {1e3 * med_now:9.1f} ms ({med_now / base[f'{what} now']:6.1f}x its"
                        f" first); ref/now {statistics.median(ratios):.2f}x"
                    )
                old, new = RefJoint().fit(rec), JointFit().fit(rec)
                worst = max(
                    abs(new.value_of(n) - old.value_of(n)) / new.std_of(n)
                    for n in new.names
                    if n.startswith(("gain_", "offset_"))
                )
                sigma = max(
                    abs(old.std_of(n) / new.std_of(n) - 1.0)
                    for n in new.names
                    if n.startswith(("gain_", "offset_"))
                )
                print(
                    f"      largest change of a gain/offset {worst:.3f} σ, of its σ"
                    f" {100 * sigma:.1f} %; AR order ref {old.noise.order}, now {new.noise.order}"
                )


if __name__ == "__main__":
    main()
