"""Calibration speed and memory: the joint fit, the whole calibration, the paper's pipeline.

Prints absolute wall times and ratios measured in this same process, one BLAS thread:

* one 90 s / 200 Hz Table I recording (rest, push, spin, brake, rest), raw samples →
  result, both for ``JointFit().fit`` (all samples, as if cut to the spin) and for the whole
  calibration the CLI runs (``SessionFit``: window search, fit, noise reference,
  motion check, gates, rest check; target ≤ 15 ms median);
* the paper's four Nelder–Mead searches on the same data (target: ≥ 50× slower than
  the whole calibration), timed interleaved with the contenders;
* how the time and the peak memory (tracemalloc, above the recording itself) grow with
  the number of samples (1×, 10×, 100×: the same 90 s at 200 Hz, 2 kHz, 20 kHz);
* ``--profile``: where the milliseconds go, stage by stage, and cProfile's top functions.

Run:  python benchmarks/bench_fit.py [--repeats 30] [--skip-100x] [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import pstats
import statistics
import tracemalloc

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import fmt, interleaved_times
from bench_versus import STAGES, stage_times
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.estimate.paper.estimator import PaperEstimator
from wheelcal.runtime import tune_allocator
from wheelcal.session.fit import SessionFit, choose_window
from wheelcal.simulate import simulate, table1


def window_of(recording):
    """The free-spin window the whole calibration would fit (found once, outside the timing)."""
    return choose_window(recording, max_window_s=SessionFit().gates.max_window_s).recording


def peak_bytes(fn) -> int:
    """Peak traced allocation while ``fn`` runs (numpy reports its buffers to tracemalloc)."""
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def stage_breakdown(recording, repeats: int) -> None:
    """Median ms of each stage of the whole calibration, run as SessionFit runs it."""
    from wheelcal.session import fit as sf

    run = stage_times(sf, recording)
    stages: dict[str, list[float]] = {}
    for _ in range(repeats + 1):
        for name, seconds in zip(STAGES, run(), strict=True):
            stages.setdefault(name, []).append(seconds)
    total = sum(statistics.median(v[1:]) for v in stages.values())
    print("where the whole calibration's time goes (median ms per stage):")
    for name, ts in stages.items():
        med = statistics.median(ts[1:])
        print(f"  {name:32s} {1e3 * med:7.2f} ms  {100 * med / total:5.1f} %")
    print(f"  {'sum':32s} {1e3 * total:7.2f} ms")


def top_functions(fn, repeats: int, count: int = 15) -> None:
    """cProfile's top functions by own time over ``repeats`` runs of ``fn``."""
    profile = cProfile.Profile()
    profile.enable()
    for _ in range(repeats):
        fn()
    profile.disable()
    print(f"cProfile, {repeats} whole calibrations, top {count} by own time:")
    pstats.Stats(profile).sort_stats("tottime").print_stats(count)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--paper-repeats", type=int, default=3)
    ap.add_argument("--skip-100x", action="store_true", help="skip the 1.8 M-sample case")
    ap.add_argument("--profile", action="store_true", help="stage breakdown and cProfile")
    args = ap.parse_args()
    with threadpool_limits(1):
        tune_allocator()  # as the CLI does (see wheelcal.runtime)
        recording = simulate(table1(), np.random.default_rng(0)).recording
        window = window_of(recording)
        contenders = {
            "joint": lambda: JointFit().fit(recording),
            "session": lambda: SessionFit().run(recording),
        }
        fast = interleaved_times(contenders, args.repeats)
        contenders["paper"] = lambda: PaperEstimator().fit(recording)
        rounds = interleaved_times(contenders, args.paper_repeats)
        print(
            f"samples: {recording.samples} x 3 axes (90 s at 200 Hz; free-spin window "
            f"{window.samples}), one BLAS thread"
        )
        print(f"joint ML fit (all samples)  : {fmt(fast['joint'])}")
        print(f"whole calibration (session) : {fmt(fast['session'])}   (target <= 15 ms)")
        print(f"paper Nelder–Mead           : {fmt(rounds['paper'])}")
        paper = statistics.median(rounds["paper"])
        for name in ("joint", "session"):
            ratios = [p / s for p, s in zip(rounds["paper"], rounds[name], strict=True)]
            print(
                f"speed-up {name:7s}/paper      : {paper / statistics.median(fast[name]):8.1f}x"
                f"   (per interleaved round: {statistics.median(ratios):.1f}x; target >= 50x)"
            )
        print("scaling with samples (same 90 s, higher rate); memory = tracemalloc peak:")
        base = {name: statistics.median(ts) for name, ts in fast.items()}
        for factor in (1, 10, 100):
            if factor == 100 and args.skip_100x:
                continue
            scenario = dataclasses.replace(table1(), rate_hz=200.0 * factor)
            rec = simulate(scenario, np.random.default_rng(1)).recording
            fns = {
                "joint": lambda r=rec: JointFit().fit(r),
                "session": lambda r=rec: SessionFit().run(r),
            }
            ts = interleaved_times(fns, max(1, args.repeats // factor))
            for name, fn in fns.items():
                med = statistics.median(ts[name])
                samples = rec.samples
                peak = peak_bytes(fn)
                print(
                    f"  {factor:4d}x {name:7s} {samples:9d} samples: {1e3 * med:9.1f} ms"
                    f" ({med / base[name]:6.1f}x the 1x time, "
                    f"{1e9 * med / samples:6.0f} ns/sample), peak {peak / 2**20:7.1f} MiB"
                    f" = {peak / samples:5.0f} B/sample"
                )
        if args.profile:
            stage_breakdown(recording, args.repeats)
            top_functions(lambda: SessionFit().run(recording), args.repeats)


if __name__ == "__main__":
    main()
