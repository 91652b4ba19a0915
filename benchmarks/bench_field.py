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

    python benchmarks/bench_field.py [--repeats 7] [--rolling-ref]

Target (issue "wheels in the field"): the car drive in ≤ 2 s on one core.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics

import numpy as np
from threadpoolctl import threadpool_limits

import wheelcal
from _timing import fmt, interleaved_times
from wheelcal.simulate import table2
from wheelcal.simulate.field import car_drive, robot_drive, simulate_field, wheelchair_coast
from wheelcal.simulate.session import simulate_session


def _recordings() -> dict:
    rng = np.random.default_rng(3)
    car = simulate_field(car_drive(rng), rng)
    rng = np.random.default_rng(3)
    robot = simulate_field(robot_drive(rng), rng)
    rng = np.random.default_rng(3)
    chair = simulate_field(wheelchair_coast(rng), rng)
    bench = simulate_session(table2(rng=np.random.default_rng(5)), np.random.default_rng(6))
    return {"car": car, "robot": robot, "wheelchair": chair, "bench": bench}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument(
        "--rolling-ref", action="store_true", help="also --geometry rolling, the radius given"
    )
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


if __name__ == "__main__":
    main()
