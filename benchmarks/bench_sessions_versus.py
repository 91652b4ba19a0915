"""CPU per session of the batch's session (read, calibrate, write) against a git revision.

In one process, one BLAS thread: this tree's ``calibrate_session`` and that of
``--ref`` (extracted as ``wheelcal_ref``, see ``bench_versus.py``) on the same
recordings, alternating recording by recording (and who goes first), each run
``--repeats`` times over the folder after a warm-up pass.  Prints each one's CPU
and wall milliseconds per session and the median of the per-pass CPU ratios
ref / now (CPU time hardly depends on the machine's other load).

Run:  python benchmarks/bench_sessions_versus.py --ref main --inputs DIR [--count 40] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

from threadpoolctl import threadpool_limits


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True)
    ap.add_argument("--inputs", required=True, help="folder of *.mcap recordings")
    ap.add_argument("--count", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    from bench_versus import extract

    where = Path(tempfile.mkdtemp(prefix="wheelcal-sessions-"))
    extract(args.ref, where)
    sys.path.insert(0, str(where))
    from wheelcal_ref.batch.session import calibrate_session as ref_calibrate
    from wheelcal_ref.session.compute import SessionOptions as RefOptions

    from wheelcal.batch.session import calibrate_session
    from wheelcal.session.compute import SessionOptions

    files = sorted(Path(args.inputs).glob("*.mcap"))[: args.count]
    runs = {
        "now": (calibrate_session, SessionOptions()),
        "ref": (ref_calibrate, RefOptions()),
    }
    cpu = {name: [] for name in runs}
    wall = {name: [] for name in runs}

    def one_pass(record: bool) -> None:
        totals = {name: [0.0, 0.0] for name in runs}
        for i, path in enumerate(files):
            for name in ("now", "ref") if i % 2 else ("ref", "now"):
                calibrate, options = runs[name]
                c0, w0 = time.process_time(), time.perf_counter()
                outcome = calibrate(str(path), options, where / name, durable=False)
                totals[name][0] += time.process_time() - c0
                totals[name][1] += time.perf_counter() - w0
                if outcome.error and record:
                    print(f"{name}: {outcome.error}")
        if record:
            for name, (c, w) in totals.items():
                cpu[name].append(c / len(files))
                wall[name].append(w / len(files))

    with threadpool_limits(limits=1):
        one_pass(record=False)  # warm-up: imports, caches
        for _ in range(args.repeats):
            one_pass(record=True)
    print(f"versus {args.ref}: {len(files)} recordings × {args.repeats} passes, one BLAS thread")
    for name in runs:
        print(
            f"{name}: CPU {1e3 * statistics.median(cpu[name]):6.1f} ms per session "
            f"(passes: {', '.join(f'{1e3 * c:.1f}' for c in cpu[name])}); "
            f"wall {1e3 * statistics.median(wall[name]):6.1f} ms"
        )
    ratio = statistics.median(r / n for r, n in zip(cpu["ref"], cpu["now"], strict=True))
    print(f"CPU per session {args.ref} / now, median of per-pass ratios: {ratio:.3f}")


if __name__ == "__main__":
    main()
