"""Gyro-aided calibration speed against the accelerometer-only fit, one core.

Prints absolute times and ratios measured in this same process, on whole
simulated sessions (90 s of motion at 200 Hz with a gyroscope, rest, push and
stop around it), through :class:`~wheelcal.session.fit.SessionFit`:

* a clean free spin: accelerometer only (``--gyro off``) against the gyro-aided
  fit forced on (``--gyro on``: spline wheel angle with knots chosen by BIC,
  gyro stream, disturbance trimming) — target ≤ 3×;
* a wheel pushed three times: ``--gyro on`` (the accelerometer alone can only use
  the stretch between two pushes).

With ``--ref REV`` the gyro-aided calibrations of the revision ``REV`` (its
``src/wheelcal`` extracted as the package ``wheelcal_ref``, see bench_versus.py)
run interleaved with this tree's, round by round, on the same samples; the
median of the per-round ratios ref / now is printed, and how far the results
differ: every reported parameter of the calibration (not the wheel's motion,
whose cubic and spline are degenerate) and the gyro block in σ of this tree's fit, the largest relative change of a σ, and whether the warnings, the
gates' verdicts and the window's reason agree.

Run:  python benchmarks/bench_gyro.py [--repeats 7] [--ref main]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import fmt, interleaved_times


def _recordings(package: str) -> dict:
    """The clean spin and the three pushes, simulated by ``package``."""
    hostile = __import__(f"{package}.simulate.hostile", fromlist=["hostile"])
    gyro_spec = __import__(f"{package}.simulate.gyro", fromlist=["GyroSpec"]).GyroSpec
    return {
        "clean": hostile.clean(np.random.default_rng(1), gyro=gyro_spec()).recording,
        "pushes": hostile.three_pushes(np.random.default_rng(9), gyro=gyro_spec()).recording,
    }


def _gyro_values(result) -> dict[str, tuple[float, float]]:
    """The gyro block's scale, axis and biases with σ, by name."""
    g = result.assessment.gyro
    out = {"gyro.scale": (g.scale, g.scale_std)}
    for i, axis in enumerate("xyz"):
        out[f"gyro.axis_{axis}"] = (g.axis[i], g.axis_std[i])
        out[f"gyro.bias_{axis}"] = (g.bias_radps[i], g.bias_std_radps[i])
    return out


def _differences(new, old) -> str:
    """How far ``old`` (the reference's outcome) lies from ``new``, in σ of ``new``."""
    a, b = new.result, old.result
    same_names = a.names == b.names
    # The calibration's parameters; the wheel's motion (cubic and spline) is degenerate
    # (the spline reproduces the cubic): its σ are not finite, and not compared.
    names = [
        n
        for n in a.names
        if not n.startswith(("theta0", "omega", "spin_spline."))
        and all(0 < x.std_of(n) < np.inf for x in (a, b))
    ]
    worst = max(abs(a.value_of(n) - b.value_of(n)) / a.std_of(n) for n in names)
    sigma = max(abs(a.std_of(n) / b.std_of(n) - 1) for n in names)
    ga, gb = _gyro_values(a), _gyro_values(b)
    gyro_worst = max(abs(ga[k][0] - gb[k][0]) / ga[k][1] for k in ga if ga[k][1] > 0)
    gyro_sigma = max(abs(ga[k][1] / gb[k][1] - 1) for k in ga if gb[k][1] > 0)
    return (
        f"    same parameter names: {same_names}; calibration ({len(names)} parameters, the wheel's "
        f"motion left out): largest change {worst:.2e} σ, of a σ "
        f"{sigma:.1e} (relative); gyro block: {gyro_worst:.2e} σ, of a σ {gyro_sigma:.1e}\n"
        f"    same warnings: {a.warnings == b.warnings}; same undetermined: "
        f"{a.assessment.undetermined == b.assessment.undetermined}; same window and notes: "
        f"{new.window.reason == old.window.reason}; same samples kept: "
        f"{a.time_s.size == b.time_s.size and np.array_equal(a.time_s, b.time_s)}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--ref", default=None, help="git revision to compare with, e.g. main")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.ref is not None:
            from bench_versus import extract

            extract(args.ref, Path(tmp))
            sys.path.insert(0, tmp)
        _run(args)


def _run(args) -> None:
    from wheelcal.runtime import tune_allocator
    from wheelcal.session.fit import SessionFit

    with threadpool_limits(1):
        tune_allocator()
        recs = _recordings("wheelcal")
        fns = {
            "acc": lambda: SessionFit(gyro="off").run(recs["clean"]),
            "gyro": lambda: SessionFit(gyro="on").run(recs["clean"]),
            "pushes": lambda: SessionFit(gyro="on").run(recs["pushes"]),
        }
        if args.ref is not None:
            from wheelcal_ref.estimate.session_fit import SessionFit as RefSessionFit

            ref_recs = _recordings("wheelcal_ref")
            fns["gyro ref"] = lambda: RefSessionFit(gyro="on").run(ref_recs["clean"])
            fns["pushes ref"] = lambda: RefSessionFit(gyro="on").run(ref_recs["pushes"])
        ts = interleaved_times(fns, args.repeats)
    clean = recs["clean"]
    print(f"session of {clean.samples} samples (90 s spin at 200 Hz + rest, push, stop), one core")
    print(f"clean spin, accelerometer only : {fmt(ts['acc'])}")
    print(f"clean spin, gyro-aided (on)    : {fmt(ts['gyro'])}")
    print(f"three pushes, gyro-aided (on)  : {fmt(ts['pushes'])}")
    acc, gyro = ts["acc"], ts["gyro"]
    ratio = statistics.median(gyro) / statistics.median(acc)
    paired = statistics.median(g / a for g, a in zip(gyro, acc, strict=True))
    print(f"gyro-aided / accelerometer-only (clean spin): {ratio:.2f}x  (target <= 3x)")
    print(f"  median of the per-round ratios (runs interleaved): {paired:.2f}x")
    if args.ref is None:
        return
    same = all(np.array_equal(recs[k].accel_mps2, ref_recs[k].accel_mps2) for k in recs)
    print(f"reference {args.ref} (same simulated samples: {same}), interleaved with the above:")
    for name, label in (("gyro", "clean spin"), ("pushes", "three pushes")):
        ref, now = ts[f"{name} ref"], ts[name]
        per_round = statistics.median(r / n for r, n in zip(ref, now, strict=True))
        print(f"  {label:13s} ref: {fmt(ref)}")
        print(f"  {label:13s} now: {fmt(now)}   ref / now per round {per_round:.2f}x")
        with threadpool_limits(1):
            key = "clean" if name == "gyro" else "pushes"
            new = SessionFit(gyro="on").run(recs[key])
            old = RefSessionFit(gyro="on").run(ref_recs[key])
        print(_differences(new, old))


if __name__ == "__main__":
    main()
