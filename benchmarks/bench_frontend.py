"""The calibration's front end, stage by stage, against an earlier revision, interleaved.

Extracts ``src/wheelcal`` at ``--ref`` as the package ``wheelcal_ref`` (see
bench_versus.py) and times, one BLAS thread, alternating round by round, the
stages of the whole calibration that surround the joint fit:

* ``find_free_spin`` (the window search), ``find_rests``;
* the closed-form start (``JointFit().start`` on the window);
* ``noise_reference`` (rests or the residual's order spectrum) and
  ``NoiseModel.estimate`` (AR order by AIC, cross-axis covariance);
* the whole calibration (``SessionFit().run``) for scale.

Each stage gets the same inputs in both trees (the reference's own recording
and rests, the same residual and wheel angle).  Prints the medians and the
median of the per-round ratios ref / now, and how far the outputs differ: the
window's ends, the start (relative), the noise reference (relative), the
calibration (in σ of the new fit).

Two recordings: ``spin`` — the 90 s / 200 Hz Table I spin of bench_fit.py (no
rests: the noise reference uses the spectrum); ``session`` — Table I with rest,
push, brake and rest around it (rests found, the floor from them).

Run:  python benchmarks/bench_frontend.py --ref main [--repeats 30] [--recording spin]
      [--rate-hz 2000]
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import statistics
from types import SimpleNamespace

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import interleaved_times
from bench_versus import reference_code


def _flat(params) -> np.ndarray:
    """The accelerometer parameters of a start as one vector."""
    parts = (
        params.spin.theta0_rad,
        params.spin.omega_radps,
        params.bench.tilt_rad,
        params.bench.radius_m,
        params.bench.misalignment.matrix,
        params.sensor.offset_mps2,
        params.sensor.gain,
    )
    return np.concatenate([np.ravel(np.asarray(p, dtype=float)) for p in parts])


def _relative(new, old) -> float:
    new, old = np.asarray(new, dtype=float), np.asarray(old, dtype=float)
    return float(np.max(np.abs(new - old) / np.maximum(np.abs(old), 1e-300)))


def _tree(package: str) -> SimpleNamespace:
    """The modules the stages live in, from ``wheelcal`` or ``wheelcal_ref``."""
    names = ("noise_model", "noise_reference", "rests", "session_fit", "window")
    tree = {name: importlib.import_module(f"{package}.estimate.{name}") for name in names}
    return SimpleNamespace(simulate=importlib.import_module(f"{package}.simulate"), **tree)


def _recording(tree: SimpleNamespace, kind: str, rate_hz: float):
    table1 = dataclasses.replace(tree.simulate.table1(), rate_hz=rate_hz)
    if kind == "spin":
        return tree.simulate.simulate(table1, np.random.default_rng(0)).recording
    return tree.simulate.simulate_session(table1, np.random.default_rng(0)).recording


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True, help="git revision to compare with, e.g. main")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--recording", choices=("spin", "session", "both"), default="both")
    ap.add_argument("--rate-hz", type=float, default=200.0, help="sample rate (Table I: 200)")
    args = ap.parse_args()
    with reference_code(args.ref):
        from wheelcal.runtime import tune_allocator

        ref, now = _tree("wheelcal_ref"), _tree("wheelcal")
        kinds = ("spin", "session") if args.recording == "both" else (args.recording,)
        with threadpool_limits(1):
            tune_allocator()
            for kind in kinds:
                _compare(kind, ref, now, args)


def _compare(kind: str, ref: SimpleNamespace, now: SimpleNamespace, args) -> None:
    """Time and compare the stages on one recording."""
    rec, ref_rec = _recording(now, kind, args.rate_hz), _recording(ref, kind, args.rate_hz)
    outcome = now.session_fit.SessionFit().run(rec)
    ref_outcome = ref.session_fit.SessionFit().run(ref_rec)
    found = now.window.find_free_spin(rec)
    ref_found = ref.window.find_free_spin(ref_rec)
    exclude = (found.start_s, found.end_s)
    rests = now.rests.find_rests(rec, exclude)
    ref_rests = ref.rests.find_rests(ref_rec, exclude)
    win, ref_win = outcome.window.recording, ref_outcome.window.recording
    fitter, ref_fitter = now.session_fit.SessionFit().fitter, ref.session_fit.SessionFit().fitter
    residual = outcome.result.residual_mps2
    theta = now.session_fit._theta(outcome.result)
    stages = {
        "window search": (
            lambda: ref.window.find_free_spin(ref_rec),
            lambda: now.window.find_free_spin(rec),
        ),
        "rests": (
            lambda: ref.rests.find_rests(ref_rec, exclude),
            lambda: now.rests.find_rests(rec, exclude),
        ),
        "closed-form start": (lambda: ref_fitter.start(ref_win), lambda: fitter.start(win)),
        "noise reference": (
            lambda: ref.noise_reference.noise_reference(residual, theta, ref_rests),
            lambda: now.noise_reference.noise_reference(residual, theta, rests),
        ),
        "NoiseModel.estimate": (
            lambda: ref.noise_model.NoiseModel.estimate(residual),
            lambda: now.noise_model.NoiseModel.estimate(residual),
        ),
        "whole calibration": (
            lambda: ref.session_fit.SessionFit().run(ref_rec),
            lambda: now.session_fit.SessionFit().run(rec),
        ),
    }
    fns = {}
    for name, (ref_fn, now_fn) in stages.items():
        fns[(name, "ref")] = ref_fn
        fns[(name, "now")] = now_fn
    ts = interleaved_times(fns, args.repeats)
    print(
        f"{kind}: {rec.samples} samples ({rec.duration_s:.0f} s at {rec.rate_hz:.0f} Hz), "
        f"{len(rests)} rests; reference {args.ref}; same samples: "
        f"{np.array_equal(rec.accel_mps2, ref_rec.accel_mps2)}; one BLAS thread"
    )
    print(f"  {'stage':22s} {'ref ms':>8s} {'now ms':>8s}   ref/now per round")
    sums = [0.0, 0.0]
    for name in stages:
        ref_ts, now_ts = ts[(name, "ref")], ts[(name, "now")]
        ratio = statistics.median([a / b for a, b in zip(ref_ts, now_ts, strict=True)])
        ref_ms, now_ms = 1e3 * statistics.median(ref_ts), 1e3 * statistics.median(now_ts)
        if name != "whole calibration":
            sums = [sums[0] + ref_ms, sums[1] + now_ms]
        print(f"  {name:22s} {ref_ms:8.2f} {now_ms:8.2f}   {ratio:5.2f}x")
        if name == "NoiseModel.estimate":
            print(f"  {'sum of the above':22s} {sums[0]:8.2f} {sums[1]:8.2f}")
    _differences(now, found, ref_found, rests, ref_rests, outcome, ref_outcome)
    start, ref_start = fitter.start(win).params, ref_fitter.start(ref_win).params
    noise = now.noise_reference.noise_reference(residual, theta, rests)
    ref_noise = ref.noise_reference.noise_reference(residual, theta, ref_rests)
    fields = ("floor_mps2", "residual_rms_mps2", "broadband_mps2", "harmonic_mps2")
    noise_diff = max(_relative(getattr(noise, f), getattr(ref_noise, f)) for f in fields)
    print(
        f"  closed-form start: largest relative change {_relative(_flat(start), _flat(ref_start)):.1e}"
        f"; noise reference (same residual): {noise_diff:.1e}"
    )


def _differences(now, found, ref_found, rests, ref_rests, outcome, ref_outcome) -> None:
    """The window, the rests and the calibration of both trees."""
    ends = (found.start_s, found.end_s) == (ref_found.start_s, ref_found.end_s)
    same_rests = [(r.start_s, r.end_s) for r in rests] == [(r.start_s, r.end_s) for r in ref_rests]
    new, old = outcome.result, ref_outcome.result
    worst = max(abs(new.value_of(n) - old.value_of(n)) / new.std_of(n) for n in new.names)
    sigma = max(abs(new.std_of(n) / old.std_of(n) - 1) for n in new.names)
    print(
        f"  window ends equal: {ends}; rests equal: {same_rests}; calibration: largest change "
        f"{worst:.1e} σ, largest relative change of a σ {sigma:.1e}; same warnings: "
        f"{new.warnings == old.warnings}"
    )


if __name__ == "__main__":
    main()
