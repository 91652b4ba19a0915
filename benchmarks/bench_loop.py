"""What the closed loop costs a calibration that needs no effect: the default against the bare model.

Times, one BLAS thread, rounds alternating (a shared machine's load drifts within
seconds, so the per-round ratio is the steady figure):

* ``default`` — the calibration every command runs (``SessionOptions().session_fit().run``:
  window, fit, checks, the closed loop's effect screen, gates);
* ``paper`` — the same with ``model="paper"`` (no screen), this tree;
* with ``--ref REV`` also that revision's ``SessionFit().run`` (its calibration then):
  the issue's "≤ 1.15× today's calibrate".

on a clean 90 s / 200 Hz Table I recording (``--session``: the whole session, with
the rest, the push, the stop and the rest around the spin, so the screen has rests
to use).  Then the screen's milliseconds by part, at the fit of that recording:
the accelerometer's information by quadrature, its score over every sample, the
rests' stream, and the tests (Schur complements, p-values).

Run:  python benchmarks/bench_loop.py [--ref 1ee26d0] [--repeats 30] [--session]
"""

from __future__ import annotations

import argparse
import contextlib
import statistics
import time

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import fmt, interleaved_times


def _recording(package, session: bool):
    scenario = package.table1()
    if session:
        from_module = package.simulate_session
        return from_module(scenario, np.random.default_rng(0)).recording
    return package.simulate(scenario, np.random.default_rng(0)).recording


def screen_parts(recording, repeats: int) -> None:
    """The screen at the default fit of ``recording``, by part (median ms)."""
    from wheelcal.closedloop import score
    from wheelcal.closedloop.loop import ClosedLoop
    from wheelcal.closedloop.rest_stream import rest_normal, usable_rests
    from wheelcal.estimate.joint.fisher_quadrature import stride_for
    from wheelcal.estimate.joint.fit import JointFit
    from wheelcal.estimate.rests import find_rests
    from wheelcal.model.effects import default_candidates
    from wheelcal.session.fit import choose_window

    choice = choose_window(recording)
    window = choice.recording
    found = choice.found
    rests = find_rests(recording, (found.start_s, found.end_s))
    fit, evaluated = JointFit().fit_evaluated(window)
    candidates = tuple(c for c in default_candidates() if c.one_recording_identifies)
    stride = stride_for(
        fit.centred_time_s, fit.params.spin, fit.noise.order, None, score.SCREEN_ROWS_PER_TURN
    )
    usable = usable_rests(fit, rests)
    parts = {
        "accelerometer: H by quadrature, g": lambda: score._normal_by_quadrature(
            fit, window, candidates, stride, evaluated
        ),
        "rests' stream": lambda: usable and rest_normal(fit, usable, candidates, fit.layout),
        "the screen (all streams, p-values)": lambda: score.screen(
            fit, window, default_candidates(), evaluated, None, rests
        ),
        "the closed loop (nothing to add)": lambda: ClosedLoop().run(window, fit, evaluated, rests),
    }
    ts = interleaved_times(parts, repeats)
    print(
        f"the screen at the fit ({len(candidates)} candidates tested, "
        f"{sum(c.size for c in candidates)} parameters, stride {stride}, "
        f"{len(usable)} rests; median ms):"
    )
    for name, values in ts.items():
        print(f"  {name:36s} {1e3 * statistics.median(values):7.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", help="git revision whose calibration to compare with, e.g. 1ee26d0")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--session", action="store_true", help="a whole session (rests around)")
    args = ap.parse_args()
    with contextlib.ExitStack() as stack:
        contenders = {}
        import wheelcal.simulate as sim
        from wheelcal.runtime import tune_allocator
        from wheelcal.session.compute import SessionOptions

        with threadpool_limits(1):
            tune_allocator()
            rec = _recording(sim, args.session)
            default = SessionOptions().session_fit()
            paper = SessionOptions(model="paper").session_fit()
            if args.ref:
                from bench_versus import reference_code

                stack.enter_context(reference_code(args.ref))
                import wheelcal_ref.simulate as ref_sim
                from wheelcal_ref.estimate.session_fit import SessionFit as RefSession

                ref_rec = _recording(ref_sim, args.session)
                same = np.array_equal(rec.accel_mps2, ref_rec.accel_mps2)
                print(f"the same samples in both trees: {same}")
                contenders[f"calibrate at {args.ref}"] = lambda: RefSession().run(ref_rec)
            contenders["calibrate, model=paper"] = lambda: paper.run(rec)
            contenders["calibrate (default: closed loop)"] = lambda: default.run(rec)
            outcome = default.run(rec)
            steps = outcome.diagnosis.steps
            print(f"effects the default added: {[s.test.effect.label() for s in steps] or 'none'}")
            t0 = time.perf_counter()
            ts = interleaved_times(contenders, args.repeats)
            print(f"({time.perf_counter() - t0:.0f} s)")
            for name, values in ts.items():
                print(f"  {name:36s} {fmt(values)}")
            now = ts["calibrate (default: closed loop)"]
            for name, values in ts.items():
                if values is now:
                    continue
                ratio = statistics.median(a / b for a, b in zip(now, values, strict=True))
                print(f"  default / {name:26s} {ratio:5.3f}x (median of per-round ratios)")
            screen_parts(rec, args.repeats)


if __name__ == "__main__":
    main()
