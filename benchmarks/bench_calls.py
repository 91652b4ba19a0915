"""Small calls on a calibration's path: this tree against a revision, interleaved in one process.

Each of these runs a few to a dozen times per calibration, so its per-call cost
(validation, argument checks, numpy's slow paths on (N, 3) arrays) adds up:

* ``Rotation.perturbed`` (the optimiser's unpack, every step);
* ``Rotation.euler_jacobian_deg`` (the reported angles' covariance);
* the χ² survival function of the motion check and the normal quantile of the
  rest check;
* the first-difference noise per axis of the joint fit's stage 1 (18 000 × 3);
* ``jacobian_transpose_times`` (the gradient passes' Jᵀu through the model) on
  17 364 samples, the free spin of the 90 s / 200 Hz Table I recording.

Prints the median µs per call of both and the median of the per-round ratios.
The reference is extracted as ``wheelcal_ref`` (see ``bench_versus.py``).

Run:  python benchmarks/bench_calls.py --ref main [--repeats 30]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import interleaved_times
from bench_versus import reference_code

#: Calls per timed round (each call takes µs: one round takes a few ms).
CALLS = 200


def per_call(fn):
    """``fn`` repeated ``CALLS`` times (one timed round)."""

    def run():
        for _ in range(CALLS):
            fn()

    return run


def contenders(rotation, ref_rotation, samples, ref_transpose_times):
    """{name: (now, ref)} of the calls to time; the same inputs for both."""
    from scipy import special, stats

    from wheelcal.estimate.joint.columns import difference_stds
    from wheelcal.model import ParameterLayout, evaluate
    from wheelcal.model.forward import jacobian_transpose_times
    from wheelcal.simulate import table1

    truth = table1().truth
    t = np.linspace(-43.4, 43.4, 17364)
    layout = ParameterLayout()
    output = evaluate(truth, t, layout)
    weights = np.random.default_rng(1).normal(size=(3, t.size))
    jtu = (truth, t, layout, weights, output)

    delta = np.array([1e-3, -2e-3, 5e-4])
    now_rot = rotation.from_euler_deg(-40.0, 10.0, 70.0)
    ref_rot = ref_rotation.from_euler_deg(-40.0, 10.0, 70.0)
    return {
        "Rotation.perturbed": (lambda: now_rot.perturbed(delta), lambda: ref_rot.perturbed(delta)),
        "euler_jacobian_deg": (now_rot.euler_jacobian_deg, ref_rot.euler_jacobian_deg),
        "chi2 survival": (lambda: special.chdtrc(12, 30.0), lambda: stats.chi2.sf(30.0, 12)),
        "normal quantile": (lambda: -special.ndtri(0.005), lambda: stats.norm.isf(0.005)),
        "difference stds": (
            lambda: difference_stds(samples),
            lambda: np.std(np.diff(samples, axis=0), axis=0),
        ),
        "Jᵀu (17 364 samples)": (
            lambda: jacobian_transpose_times(*jtu),
            lambda: ref_transpose_times(*jtu),
        ),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True, help="git revision to compare with, e.g. main")
    ap.add_argument("--repeats", type=int, default=30)
    args = ap.parse_args()
    with reference_code(args.ref):
        from wheelcal_ref.model.forward import jacobian_transpose_times as ref_transpose_times
        from wheelcal_ref.model.rotation import Rotation as RefRotation

        from wheelcal.model.rotation import Rotation
        from wheelcal.runtime import tune_allocator

        with threadpool_limits(1):
            tune_allocator()
            samples = np.random.default_rng(0).normal(0.0, 3.0, (18000, 3))
            calls = contenders(Rotation, RefRotation, samples, ref_transpose_times)
            fns = {}
            for name, (now, ref) in calls.items():
                fns[f"{name}, ref"] = per_call(ref)
                fns[f"{name}, now"] = per_call(now)
            ts = interleaved_times(fns, args.repeats, clock=time.perf_counter)
    print(f"reference {args.ref}; one BLAS thread; µs per call, median of {args.repeats} rounds")
    for name in calls:
        ref, now = ts[f"{name}, ref"], ts[f"{name}, now"]
        ratio = statistics.median(a / b for a, b in zip(ref, now, strict=True))
        print(
            f"{name:20s}: ref {1e6 * statistics.median(ref) / CALLS:8.1f} µs   "
            f"now {1e6 * statistics.median(now) / CALLS:8.1f} µs   ref / now {ratio:6.1f}x"
        )


if __name__ == "__main__":
    main()
