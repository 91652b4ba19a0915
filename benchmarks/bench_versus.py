"""This tree's calibration against an earlier revision's, interleaved in one process.

Extracts ``src/wheelcal`` at ``--ref`` (a git revision) into a temporary folder
as the package ``wheelcal_ref`` (its imports renamed), then times, one BLAS
thread, alternating round by round on the same 90 s / 200 Hz Table I
recording (``--scenario table2``: bench_batch.py's recording number
``--session``, a Table II bench; the default, 1, has AR(1) noise):

* the joint fit (``JointFit().fit``) of both;
* the whole calibration (``SessionFit().run``: window search, fit, noise
  reference, motion check, gates) of both;

and prints both medians and the median of the per-round ratios (robust to the
load of a shared machine drifting within seconds).  It also prints the largest
difference of the sensor parameters between the two, in the new fit's σ, and
that of every reported value and of every σ.

``--stages`` also times each stage of the calibration (those of ``bench_fit.py
--profile``), rounds alternating, with each stage's median ratio per round.

Run:  python benchmarks/bench_versus.py --ref 7870c1d [--repeats 30] [--stages] [--scenario table2 [--session 1]]
"""

from __future__ import annotations

import argparse
import contextlib
import inspect
import itertools
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import fmt, interleaved_times

ROOT = Path(__file__).resolve().parents[1]


def extract_source(ref: str, into: Path) -> Path:
    """``src/wheelcal`` at ``ref`` under ``into/src``; returns that ``src`` folder."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", ref, "src/wheelcal"],
        check=True,
        capture_output=True,
    ).stdout
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    return into / "src"


def extract(ref: str, into: Path) -> None:
    """``src/wheelcal`` at ``ref`` as the package ``into/wheelcal_ref``."""
    package = into / "wheelcal_ref"
    (extract_source(ref, into) / "wheelcal").rename(package)
    pattern = re.compile(r"\bwheelcal(?=[.\s])")
    for path in package.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        path.write_text(
            "\n".join(
                pattern.sub("wheelcal_ref", line)
                if line.lstrip().startswith(("from wheelcal", "import wheelcal"))
                else line
                for line in text.splitlines()
            )
            + "\n",
            encoding="utf-8",
        )


@contextlib.contextmanager
def reference_code(ref: str):
    """``wheelcal_ref`` importable for the block: revision ``ref``'s package in a temp folder."""
    with tempfile.TemporaryDirectory() as tmp:
        extract(ref, Path(tmp))
        sys.path.insert(0, tmp)
        try:
            yield
        finally:
            sys.path.remove(tmp)


STAGES = (
    "window search",
    "rests",
    "closed-form start",
    "joint fit",
    "noise reference + motion check",
    "gates + rest check",
)


def _session_fit_module():
    """The reference's ``SessionFit`` module: ``session/fit.py`` (since 72ec4f7), else
    ``estimate/session_fit.py``."""
    import importlib

    try:
        return importlib.import_module("wheelcal_ref.session.fit")
    except ModuleNotFoundError:
        return importlib.import_module("wheelcal_ref.estimate.session_fit")


def stage_times(session_fit_module, recording):
    """A function that runs the stages of ``SessionFit().run`` once, seconds per stage.

    The same stages as ``bench_fit.py --profile``, for this tree's or the
    reference's ``wheelcal.session.fit``.
    """
    sf = session_fit_module
    session = sf.SessionFit()
    gates = session.gates
    # The fit's last evaluation serves the motion check, as SessionFit runs it (not
    # in revisions before JointFit.fit_evaluated).
    keeps = hasattr(session.fitter, "fit_evaluated")
    # ... and the window search's fastest |ω| the start (not before JointFit.start took it).
    hints = "fastest_radps" in inspect.signature(session.fitter.start).parameters

    def run() -> list[float]:
        marks = [time.perf_counter()]
        choice = sf.choose_window(recording, None, None, gates.max_window_s)
        marks.append(time.perf_counter())
        rests = sf.find_rests(recording, (choice.found.start_s, choice.found.end_s))
        marks.append(time.perf_counter())
        if hints:  # the window search's fastest |ω| sets the start's thinning
            found = choice.found
            fastest = max(abs(found.omega_start_radps), abs(found.omega_end_radps))
            guess = session.fitter.start(choice.recording, fastest)
        else:
            guess = session.fitter.start(choice.recording)
        marks.append(time.perf_counter())
        if keeps:
            result, evaluated = session.fitter.fit_evaluated(choice.recording, guess=guess)
        else:
            result = session.fitter.fit(choice.recording, guess=guess)
        marks.append(time.perf_counter())
        if keeps:
            motion, reference = sf._motion(result, choice.recording, rests, evaluated)
        else:
            motion, reference = sf._motion(result, choice.recording, rests)
        marks.append(time.perf_counter())
        sf.assess(result, rests, gates, motion, reference=reference)
        marks.append(time.perf_counter())
        return [b - a for a, b in itertools.pairwise(marks)]

    return run


def print_stages(ref_run, now_run, repeats: int) -> None:
    """Both stage breakdowns, rounds alternating, and each stage's median ratio per round."""
    ref_run(), now_run()  # warm-up
    ref, now = [], []
    for _ in range(repeats):
        ref.append(ref_run())
        now.append(now_run())
    print("stages of the whole calibration, interleaved (median ms; ref / now per round):")
    for k, name in enumerate(STAGES):
        a, b = [r[k] for r in ref], [r[k] for r in now]
        ratio = statistics.median(x / y for x, y in zip(a, b, strict=True))
        print(
            f"  {name:32s} ref {1e3 * statistics.median(a):6.2f}   "
            f"now {1e3 * statistics.median(b):6.2f}   {ratio:5.2f}x"
        )
    sums = [(sum(x), sum(y)) for x, y in zip(ref, now, strict=True)]
    print(
        f"  {'sum':32s} ref {1e3 * statistics.median(x for x, _ in sums):6.2f}   "
        f"now {1e3 * statistics.median(y for _, y in sums):6.2f}   "
        f"{statistics.median(x / y for x, y in sums):5.2f}x"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True, help="git revision to compare with, e.g. 7870c1d")
    ap.add_argument("--repeats", type=int, default=30)
    ap.add_argument("--stages", action="store_true", help="also time each stage of the calibration")
    ap.add_argument("--scenario", choices=("table1", "table2"), default="table1")
    ap.add_argument("--session", type=int, default=1, help="table2: bench_batch.py's recording")
    args = ap.parse_args()
    with reference_code(args.ref):
        import wheelcal_ref.simulate as ref_sim
        from wheelcal_ref.estimate.joint import JointFit as RefJoint

        ref_session_fit = _session_fit_module()
        RefSession = ref_session_fit.SessionFit

        import wheelcal.simulate as sim
        from wheelcal.estimate.joint.fit import JointFit
        from wheelcal.runtime import tune_allocator
        from wheelcal.session.fit import SessionFit

        def recording(package):
            if args.scenario == "table1":
                return package.simulate(package.table1(), np.random.default_rng(0)).recording
            rng = np.random.default_rng([99, args.session])  # as bench_batch.py makes it
            return package.simulate(package.table2(rng=rng), rng).recording

        with threadpool_limits(1):
            tune_allocator()
            rec = recording(sim)
            ref_rec = recording(ref_sim)
            same = np.array_equal(rec.accel_mps2, ref_rec.accel_mps2)
            ts = interleaved_times(
                {
                    "joint fit, ref": lambda: RefJoint().fit(ref_rec),
                    "joint fit, now": lambda: JointFit().fit(rec),
                    "calibration, ref": lambda: RefSession().run(ref_rec),
                    "calibration, now": lambda: SessionFit().run(rec),
                },
                args.repeats,
            )
            new = SessionFit().run(rec).result
            old = RefSession().run(ref_rec).result
        print(
            f"reference {args.ref}; {args.scenario}; same simulated samples in both: {same}; one BLAS thread"
        )
        for name, values in ts.items():
            print(f"{name:18s}: {fmt(values)}")
        for what in ("joint fit", "calibration"):
            ratios = [a / b for a, b in zip(ts[f"{what}, ref"], ts[f"{what}, now"], strict=True)]
            print(f"{what:18s}: ref / now per round, median {statistics.median(ratios):.2f}x")
        worst = max(
            abs(new.value_of(n) - old.value_of(n)) / new.std_of(n)
            for n in new.names
            if n.startswith(("gain_", "offset_"))
        )
        print(f"largest change of a gain or offset between the two: {worst:.3f} σ")
        sigma = np.sqrt(np.diag(new.covariance))
        sigma_old = np.sqrt(np.diag(old.covariance))
        moved = np.max(np.abs(new.values - old.values) / sigma)
        print(
            f"largest change of any reported value: {moved:.2e} σ; of any σ: "
            f"{np.max(np.abs(sigma / sigma_old - 1)):.2e} (relative)"
        )
        if args.stages:
            from wheelcal.session import fit as session_fit

            with threadpool_limits(1):
                print_stages(
                    stage_times(ref_session_fit, ref_rec),
                    stage_times(session_fit, rec),
                    args.repeats,
                )


if __name__ == "__main__":
    main()
