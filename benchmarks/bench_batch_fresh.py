"""Batch CPU and throughput against a git revision, each batch in a fresh process (as the CLI).

``bench_batch.py --ref`` runs both packages' batches in one process: their
worker pools then share one fork server (preloaded by whichever batch came
first), and only the batch process's own CPU is counted — a forkserver
worker is the fork server's child, not the batch's, so its CPU never reaches
``RUSAGE_CHILDREN``.  Here every batch runs in a process of its own, started
afresh like ``wheelcal batch`` (the revision's ``src/wheelcal`` extracted
under its own name, on its own ``PYTHONPATH``), and the CPU counted is the
whole tree's: the batch process (imports included), its reaped children, and
its live descendants with the children *they* reaped (the fork server and
its workers).  Rounds alternate (and swap who goes first): on a shared
machine the load drifts; CPU seconds per session hardly depend on it.

Prints, per contender, the median sessions/s (of ``run_batch``'s wall time)
and the median CPU ms per session (the whole process tree, start-up
included), and the medians of the per-round ratios ref / now of both.

Run:  python benchmarks/bench_batch_fresh.py --ref main --inputs DIR [--workers 2] [--rounds 3]
      (DIR: ``*.mcap`` recordings, e.g. those ``bench_batch.py --keep DIR`` generated)
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _child(out: str, inputs: str, workers: int) -> None:
    """One batch in this fresh process; prints its wall time and the tree's CPU as JSON."""
    import psutil

    from wheelcal.batch.pipeline import load_pipeline
    from wheelcal.batch.runner import run_batch

    toml = Path(out) / "pipeline.toml"
    toml.parent.mkdir(parents=True, exist_ok=True)
    toml.write_text(
        f"[pipeline]\nname='bench'\noutput='{out}/batch'\n[inputs]\nglobs=['{inputs}/*.mcap']\n"
        f"[run]\nrerun=false\n[executor]\nworkers={workers}\n"
    )
    t0 = time.perf_counter()
    outcome = run_batch(load_pipeline(toml))
    wall = time.perf_counter() - t0
    assert not outcome.failed, outcome.failed[:3]
    live = 0.0
    for proc in psutil.Process().children(recursive=True):  # the fork server, if any
        try:
            times = proc.cpu_times()
        except psutil.NoSuchProcess:
            continue
        live += times.user + times.system + times.children_user + times.children_system
    ended = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = time.process_time() + ended.ru_utime + ended.ru_stime + live
    print(json.dumps({"wall_s": wall, "cpu_s": cpu, "sessions": len(outcome.records)}))


def _run(src: Path, scratch: Path, inputs: Path, workers: int) -> dict:
    shutil.rmtree(scratch, ignore_errors=True)
    env = {**os.environ, "PYTHONPATH": str(src)}
    done = subprocess.run(
        [sys.executable, __file__, "--child", str(scratch), str(inputs), str(workers)],
        env=env,
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ref", required=True, help="git revision to compare with, e.g. main")
    ap.add_argument("--inputs", required=True, help="folder of *.mcap recordings")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    from bench_versus import extract_source

    where = Path(tempfile.mkdtemp(prefix="wheelcal-fresh-"))
    (where / "ref").mkdir()
    sources = {"ref": extract_source(args.ref, where / "ref"), "now": ROOT / "src"}
    inputs = Path(args.inputs).resolve()
    rows: dict[str, list[dict]] = {"ref": [], "now": []}
    for i in range(args.rounds):
        for name in ("now", "ref") if i % 2 else ("ref", "now"):
            rows[name].append(_run(sources[name], where / f"out_{name}", inputs, args.workers))
    sessions = rows["now"][0]["sessions"]
    print(
        f"versus {args.ref}: {sessions} sessions, {args.workers} worker(s), no Rerun, "
        f"{args.rounds} alternating rounds, each batch in a fresh process"
    )
    for name, runs in rows.items():
        rates = ", ".join(f"{sessions / r['wall_s']:.1f}" for r in runs)
        cpus = ", ".join(f"{1e3 * r['cpu_s'] / sessions:.1f}" for r in runs)
        print(
            f"{name}: median {sessions / statistics.median(r['wall_s'] for r in runs):5.1f} "
            f"sessions/s ({rates}); CPU median "
            f"{1e3 * statistics.median(r['cpu_s'] for r in runs) / sessions:.1f} ms per session "
            f"({cpus}; whole process tree)"
        )
    for what, key in (("throughput", "wall_s"), ("CPU per session", "cpu_s")):
        ratio = statistics.median(
            r[key] / n[key] for r, n in zip(rows["ref"], rows["now"], strict=True)
        )
        print(f"{what}: {args.ref} / now, median of per-round ratios: {ratio:.3f}")
    shutil.rmtree(where, ignore_errors=True)


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--child":
        _child(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    else:
        main()
