"""Rerun logging speed: writing a session's .rrd against fitting it, one core, same process.

The batch should be limited by the fit, not by logging.  Prints, for one
90 s / 200 Hz Table I recording (18 001 samples × 3 axes):

* the joint fit (raw samples → result);
* ``write_session_rrd`` (encode + atomic write with fsync), and its ratio to the fit;
  in wall time and in process CPU time; also as a batch writes it
  (``durable=False``: no fsync per file, the batch syncs once at its end);
* ``write_batch_rrd`` for many sessions' calibration dictionaries;
* with ``--ref REV``: ``write_session_rrd`` of this tree against the one of an
  earlier git revision (extracted as ``wheelcal_ref``, as in
  ``bench_versus.py``), interleaved round by round in this process, each on
  its own fit of the same recording; medians and the median of the per-round
  ratios, wall and process CPU time.

Run:  python benchmarks/bench_rrd.py [--repeats 20] [--out DIR] [--ref e410f15]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from _timing import fmt, interleaved_times, times
from bench_versus import reference_code
from wheelcal.calibration.session_json import calibration_dict
from wheelcal.estimate.joint.fit import JointFit
from wheelcal.runtime import tune_allocator
from wheelcal.session.fit import session_of_fit
from wheelcal.simulate import simulate, table1
from wheelcal.viz.batch_rrd import write_batch_rrd
from wheelcal.viz.session_rrd import write_session_rrd


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--batch-sessions", type=int, default=50)
    ap.add_argument(
        "--out", type=Path, default=None, help="directory for the files (default: temp)"
    )
    ap.add_argument("--ref", default=None, help="git revision to compare write_session_rrd with")
    args = ap.parse_args()
    tune_allocator()  # as the CLI and the batch workers do (see wheelcal.runtime)
    with tempfile.TemporaryDirectory() as tmp, threadpool_limits(1):
        out = args.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        recording = simulate(table1(), np.random.default_rng(0)).recording
        result = JointFit().fit(recording)
        session = session_of_fit(result, recording)
        fit = times(lambda: JointFit().fit(recording), args.repeats)
        path = out / "session.rrd"
        write = times(lambda: write_session_rrd(path, session), args.repeats)
        write_batchlike = times(
            lambda: write_session_rrd(path, session, durable=False), args.repeats
        )
        sessions = []
        for i in range(args.batch_sessions):
            d = calibration_dict(session)
            d["source"]["sensor_id"] = f"imu{i % 3}"
            sessions.append(d)
        # Process CPU time (Rerun encodes on its own threads): robust to a busy machine.
        fit_cpu = times(lambda: JointFit().fit(recording), args.repeats, time.process_time)
        write_cpu = times(
            lambda: write_session_rrd(path, session),
            args.repeats,
            time.process_time,
        )
        batch_path = out / "batch.rrd"
        batch = times(lambda: write_batch_rrd(batch_path, sessions), max(3, args.repeats // 4))
        print(f"samples: {recording.samples} x 3 axes (90 s at 200 Hz), one BLAS thread")
        print(f"joint fit              : {fmt(fit)}")
        print(f"write_session_rrd      : {fmt(write)}   ({path.stat().st_size / 1e6:.1f} MB)")
        print(
            f"  as a batch writes it : {fmt(write_batchlike)}   (no fsync per file: a batch syncs once at its end)"
        )
        ratio = statistics.median(write) / statistics.median(fit)
        print(f"write / fit (wall)     : {ratio:8.2f}   (the batch is limited by the fit if << 1)")
        print(f"joint fit, CPU         : {fmt(fit_cpu)}")
        print(f"write_session_rrd, CPU : {fmt(write_cpu)}")
        ratio = statistics.median(write_cpu) / statistics.median(fit_cpu)
        print(f"write / fit (CPU)      : {ratio:8.2f}")
        print(
            f"write_batch_rrd ({args.batch_sessions} sessions, 3 sensors): {fmt(batch)}"
            f"   ({batch_path.stat().st_size / 1e6:.2f} MB)"
        )
        if args.ref:
            versus(args.ref, session, out, args.repeats)


def versus(ref: str, session, out: Path, repeats: int) -> None:
    """``write_session_rrd`` of ``ref`` and of this tree, interleaved; wall and CPU."""
    with reference_code(ref):
        from wheelcal_ref.estimate.joint.fit import JointFit as RefJoint
        from wheelcal_ref.session.fit import session_of_fit as ref_session_of_fit
        from wheelcal_ref.simulate import simulate as ref_simulate
        from wheelcal_ref.simulate import table1 as ref_table1
        from wheelcal_ref.viz.session_rrd import write_session_rrd as ref_write

        ref_recording = ref_simulate(ref_table1(), np.random.default_rng(0)).recording
        ref_session = ref_session_of_fit(RefJoint().fit(ref_recording), ref_recording)
        # as a batch writes them: no fsync per file; this tree's with the JSON it shares
        document = calibration_dict(session)
        fns = {
            "ref": lambda: ref_write(out / "ref.rrd", ref_session, False),
            "now": lambda: write_session_rrd(out / "now.rrd", session, False, document),
        }
        sizes = {}
        for clock, what in ((time.perf_counter, "wall"), (time.process_time, "CPU")):
            ts = interleaved_times(fns, repeats, clock)
            ratios = [a / b for a, b in zip(ts["ref"], ts["now"], strict=True)]
            for name, values in ts.items():
                print(
                    f"write_session_rrd {name} ({ref if name == 'ref' else 'this tree'}), {what}: "
                    f"{fmt(values)}"
                )
            print(f"  ref / now per round ({what}), median {statistics.median(ratios):.2f}x")
        for name in fns:
            sizes[name] = (out / f"{name}.rrd").stat().st_size / 1e6
        print(f"file size: ref {sizes['ref']:.2f} MB, now {sizes['now']:.2f} MB")


if __name__ == "__main__":
    main()
