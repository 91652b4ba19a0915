"""A wheel in the field against a bench session: the default calibration of each, one core.

Times ``wheelcal.calibrate(recording)`` — the default path, ``--geometry auto``,
no radius given — on a simulated two-minute car drive at 120 Hz (speed changes,
turns, stops, road vibration; ``wheelcal.simulate.field.car_drive``), a 90 s
robot drive and a wheelchair's coast, interleaved with a 90 s / 200 Hz bench
session (the paper's Table II, radius given) in the same process, one BLAS
thread.  Prints absolute times, the ratio to the bench, and, with
``--rolling-ref``, the same car drive with ``--geometry rolling`` and the radius
given (the field fit asked for by name, r held; it was the joint fit's spline
rolling geometry before issue 41 item 6).

    python benchmarks/bench_field.py [--repeats 7] [--rolling-ref] [--ref REV]

``--ref REV`` also times revision REV's calibration of the same drives (its own
simulator, the same seeds; ``bench_versus.py``'s extraction), round by round with
this tree's, and prints each drive's median per-round ratio, this tree over REV's.

Target (issue "wheels in the field"): the car drive in ≤ 2 s on one core.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import statistics

import numpy as np
from threadpoolctl import threadpool_limits

import wheelcal
from _timing import fmt, interleaved_times
from bench_versus import reference_code


def _recordings(package=wheelcal) -> dict:
    """The drives and the bench session, simulated by ``package`` (this tree's or a ref's)."""
    simulate = importlib.import_module(f"{package.__name__}.simulate")
    field = importlib.import_module(f"{package.__name__}.simulate.field")
    session = importlib.import_module(f"{package.__name__}.simulate.session")
    out = {}
    for name, kind in (
        ("car", field.car_drive),
        ("robot", field.robot_drive),
        ("wheelchair", field.wheelchair_coast),
    ):
        rng = np.random.default_rng(3)
        out[name] = field.simulate_field(kind(rng), rng)
    table = simulate.table2(rng=np.random.default_rng(5))
    out["bench"] = session.simulate_session(table, np.random.default_rng(6))
    return out


def _ref_ratios(ref: str, recs: dict, repeats: int) -> None:
    """Each recording's median per-round ratio, this tree's calibration over ``ref``'s."""
    with reference_code(ref):
        import wheelcal_ref

        # the API module itself: the root's lazy names are strings naming ``wheelcal``
        their_calibrate = importlib.import_module("wheelcal_ref.api").calibrate
        theirs = _recordings(wheelcal_ref)
        fns = {}
        for name in recs:
            fns[name] = lambda r=recs[name].recording: wheelcal.calibrate(r)
            fns[f"{name} ({ref})"] = lambda r=theirs[name].recording: their_calibrate(r)
        with threadpool_limits(1):
            ts = interleaved_times(fns, repeats)
    print(f"against {ref}, interleaved round by round:")
    for name in recs:
        mine, old = ts[name], ts[f"{name} ({ref})"]
        ratio = statistics.median(a / b for a, b in zip(mine, old, strict=True))
        print(f"  {name:12s} {fmt(mine)}  {ref}: {fmt(old)}  ratio {ratio:.2f}")
    car = [a / b for a, b in zip(ts["car"], ts["bench"], strict=True)]
    old = [a / b for a, b in zip(ts[f"car ({ref})"], ts[f"bench ({ref})"], strict=True)]
    print(
        f"  car / bench per round: this tree {statistics.median(car):.1f}×, "
        f"{ref} {statistics.median(old):.1f}×"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument(
        "--rolling-ref", action="store_true", help="also --geometry rolling, the radius given"
    )
    ap.add_argument("--ref", help="a git revision to time against, round by round")
    args = ap.parse_args()
    recs = _recordings()
    car = recs["car"].recording
    print(
        f"car drive: {car.time_s[-1] - car.time_s[0]:.0f} s at {car.rate_hz:.0f} Hz "
        f"({car.time_s.size} samples); bench: Table II, "
        f"{recs['bench'].recording.time_s.size} samples"
    )
    fns = {name: (lambda r=sim.recording: wheelcal.calibrate(r)) for name, sim in recs.items()}
    if args.rolling_ref:
        given = dataclasses.replace(
            car, info=car.info.merged(radius_m=float(recs["car"].truth.bench.radius_m))
        )
        fns["car, rolling, radius given"] = lambda: wheelcal.calibrate(given, geometry="rolling")
    with threadpool_limits(1):
        ts = interleaved_times(fns, args.repeats)
    bench = statistics.median(ts["bench"])
    for name, values in ts.items():
        ratio = statistics.median(values) / bench
        print(f"  {name:26s} {fmt(values)}   {ratio:6.1f}× the bench session")
    verdict = "met" if statistics.median(ts["car"]) <= 2.0 else "NOT met"
    print(f"target: the car drive in ≤ 2 s on one core — {verdict}")
    if args.ref:
        _ref_ratios(args.ref, recs, args.repeats)


if __name__ == "__main__":
    main()
