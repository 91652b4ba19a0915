"""The batch as a user runs it: ``wheelcal batch`` in a fresh process, this tree against a revision.

``bench_batch.py`` runs its batches inside one Python process (after its
1-worker runs have calibrated every session in that process).  A user's
``wheelcal batch`` starts fresh: imports, planning, worker start-up, the
sessions, the report and the final sync all count, and so does what the
parent imports before its workers fork.  This script times exactly that, wall
clock from launch to exit, for this tree and for ``--ref`` (its ``src``
extracted to a temporary folder and put first on ``PYTHONPATH``), alternating
round by round (the machine's load drifts: on the shared development machine
the CPU time of one and the same batch varied by a quarter within an hour), on
the recordings of ``bench_batch.py --keep DIR`` (made there if missing), each
run into an empty output folder.  Prints every run's sessions/s and the median
per-round ratio, with and without Rerun.

Targets (issue 15): 1,000 recordings on 2 workers ≥ 40 sessions/s without
Rerun, ≥ 25 with it.

Run:  python benchmarks/bench_cli_batch.py --keep /tmp/bb1000 --ref 4c9b56f [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_batch import _make_recordings
from bench_versus import extract_source

ROOT = Path(__file__).resolve().parents[1]


def _pipeline(root: Path, inputs: Path, out: Path, rerun: bool) -> Path:
    toml = root / f"cli_{'rrd' if rerun else 'norrd'}.toml"
    toml.write_text(
        f"[pipeline]\nname='bench'\noutput='{out}'\n[inputs]\nglobs=['{inputs}/*.mcap']\n"
        f"[run]\nrerun={'true' if rerun else 'false'}\n[executor]\nworkers=2\n"
    )
    return toml


def _run(src: Path, toml: Path, out: Path, sessions: int) -> float:
    """Wall seconds of one ``wheelcal batch`` from ``src`` into an emptied ``out``."""
    shutil.rmtree(out, ignore_errors=True)
    env = {**os.environ, "PYTHONPATH": str(src)}
    command = [sys.executable, "-m", "wheelcal.cli.main", "batch", str(toml)]
    t0 = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if done.returncode != 0 or f"{sessions} calibrated" not in done.stdout + done.stderr:
        raise SystemExit(f"batch from {src} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", metavar="DIR", required=True, help="recordings (and outputs) here")
    ap.add_argument("--sessions", type=int, default=1000)
    ap.add_argument("--ref", required=True, help="git revision to compare with, e.g. 4c9b56f")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    root = Path(args.keep)
    inputs = root / "recordings"
    inputs.mkdir(parents=True, exist_ok=True)
    _make_recordings(inputs, args.sessions)
    if len(list(inputs.glob("*.mcap"))) != args.sessions:
        raise SystemExit(f"{inputs} must hold exactly {args.sessions} recordings")
    out = root / "cli_out"
    with tempfile.TemporaryDirectory() as tmp:
        trees = {"ref": extract_source(args.ref, Path(tmp)), "now": ROOT / "src"}
        for rerun in (False, True):
            toml = _pipeline(root, inputs, out, rerun)
            walls: dict[str, list[float]] = {"ref": [], "now": []}
            for k in range(args.rounds):
                for name, src in trees.items():
                    walls[name].append(_run(src, toml, out, args.sessions))
                    print(
                        f"rerun={'on ' if rerun else 'off'} round {k + 1} {name}: "
                        f"{walls[name][-1]:5.1f} s  {args.sessions / walls[name][-1]:5.1f} sessions/s",
                        flush=True,
                    )
            ratio = statistics.median(
                a / b for a, b in zip(walls["ref"], walls["now"], strict=True)
            )
            print(
                f"rerun={'on ' if rerun else 'off'}: ref {args.ref} median "
                f"{args.sessions / statistics.median(walls['ref']):.1f} sessions/s, now "
                f"{args.sessions / statistics.median(walls['now']):.1f} sessions/s; "
                f"ref / now wall per round {ratio:.2f}x"
            )
    shutil.rmtree(out, ignore_errors=True)


if __name__ == "__main__":
    main()
