"""Batch throughput: sessions per second with 1 and 2 workers, with and without Rerun output.

Generates N recordings (90 s at 200 Hz, Table II bench, a different hand spin
each, ROS 2 MCAP) once, then runs the same batch four times into fresh output
folders and prints, measured in this process:

* sessions per second for each run and the ratios (2 workers vs 1, Rerun on vs off);
* the per-session cost breakdown (read, window search, fit, Rerun, JSON) from
  the sessions' own timings, and what share of a session the fit is;
* with ``--dask``: the same batch (2 workers, no Rerun) on a Dask
  ``LocalCluster`` of 2 single-threaded worker processes, run alternately with
  the local process pool (``--rounds`` times each), and the ratio of their
  throughputs (target ≥ 0.9).

With ``--ref REV`` (a git revision, e.g. ``main``): instead, this tree's
batch against that revision's (extracted as ``wheelcal_ref``, see
``bench_versus.py``) in this process, alternating round by round, on the local
pool (2 workers, no Rerun) and, with ``--dask``, on one Dask ``LocalCluster``
(its workers warmed with both packages first); prints each one's sessions/s
and CPU seconds per session (all processes: on a saturated machine throughput
is bounded by CPU per session, and CPU time hardly depends on the machine's
other load), and the medians of the per-round ratios of both.

Targets (issue 15): 1,000 recordings on 2 workers ≥ 40 sessions/s without
Rerun, ≥ 25 with it; Dask ≥ 90 % of the local processes.

Run:  python benchmarks/bench_batch.py [--sessions 1000] [--keep DIR] [--dask] [--rounds 3]
      python benchmarks/bench_batch.py --sessions 200 --ref main [--dask] [--rounds 5]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from wheelcal.batch.pipeline import load_pipeline
from wheelcal.batch.runner import run_batch


def _make_recordings(folder: Path, count: int) -> float:
    from wheelcal.io import write_recording
    from wheelcal.simulate import simulate, table2

    t0 = time.perf_counter()
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(count):
        path = folder / f"r{i:05d}.mcap"
        if path.exists():
            continue
        rng = np.random.default_rng([99, i])
        rec = simulate(table2(rng=rng), rng).recording
        info = rec.info.merged(sensor_id="bench", mounting_id="m1")
        write_recording(rec.__class__(rec.time_s, rec.accel_mps2, info, rec.epoch_unix_ns), path)
    return time.perf_counter() - t0


def _run(
    root: Path,
    inputs: Path,
    workers: int,
    rerun: bool,
    dask_address: str | None = None,
    api=(run_batch, load_pipeline),
    suffix: str = "",
):
    tag = ("dask" if dask_address else f"w{workers}") + suffix
    out = root / f"out_{tag}_{'rrd' if rerun else 'norrd'}"
    shutil.rmtree(out, ignore_errors=True)
    toml = root / f"p_{tag}_{rerun}.toml"
    executor = (
        f"kind='dask'\naddress='{dask_address}'\n" if dask_address else f"workers={workers}\n"
    )
    toml.write_text(
        f"[pipeline]\nname='bench'\noutput='{out}'\n[inputs]\nglobs=['{inputs}/*.mcap']\n"
        f"[run]\nrerun={'true' if rerun else 'false'}\n[executor]\n{executor}"
    )
    run, load = api
    cpu0 = _cpu_s(dask_address is not None)
    t0 = time.perf_counter()
    outcome = run(load(toml))
    wall = time.perf_counter() - t0
    _run.last_cpu_s = _cpu_s(dask_address is not None) - cpu0
    assert not outcome.failed, outcome.failed[:3]
    return wall, outcome


def _cpu_s(live_descendants: bool) -> float:
    """CPU seconds of this process (with the Dask scheduler and client threads), of its ended
    children, of the fork server (a live child) with the workers it has reaped (the local
    pool's: a forkserver worker is the server's child, never this process's) and, if asked,
    of its other live descendants (Dask's nannies and workers; not for a local run, which
    they only watch idling).

    On a saturated machine a batch's throughput is bounded by its CPU per session, and CPU
    time, unlike the wall clock, hardly depends on what else the machine runs.
    """
    import psutil  # with distributed; without it the live descendants are not counted

    ended = resource.getrusage(resource.RUSAGE_CHILDREN)
    live = 0.0
    for child in psutil.Process().children(recursive=True):
        try:
            forkserver = "forkserver" in " ".join(child.cmdline())
            if not (live_descendants or forkserver):
                continue
            times = child.cpu_times()
        except psutil.NoSuchProcess:
            continue
        live += times.user + times.system
        if forkserver:
            live += times.children_user + times.children_system
    return time.process_time() + ended.ru_utime + ended.ru_stime + live


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=1000)
    ap.add_argument("--keep", metavar="DIR", help="reuse/keep recordings and outputs here")
    ap.add_argument("--dask", action="store_true", help="also compare a Dask LocalCluster")
    ap.add_argument("--rounds", type=int, default=3, help="alternating dask/local runs")
    ap.add_argument("--skip-local", action="store_true", help="only the Dask comparison")
    ap.add_argument("--ref", help="compare with this git revision's batch instead, e.g. main")
    args = ap.parse_args()
    root = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="wheelcal-bench-"))
    inputs = root / "recordings"
    gen = _make_recordings(inputs, args.sessions)
    print(
        f"{args.sessions} recordings (90 s, 200 Hz, ROS 2 MCAP) in {inputs} (generated in {gen:.0f} s)"
    )
    if args.ref:
        _versus_ref(args.ref, root, inputs, args.sessions, args.rounds, args.dask)
        return
    if args.dask:
        _compare_dask(root, inputs, args.sessions, args.rounds)
    if args.skip_local:
        return
    results = {}
    for workers in (1, 2):
        for rerun in (False, True):
            wall, outcome = _run(root, inputs, workers, rerun)
            results[(workers, rerun)] = (wall, outcome)
            rate = args.sessions / wall
            print(
                f"workers={workers} rerun={'on ' if rerun else 'off'}: {wall:7.1f} s  {rate:6.1f} sessions/s"
            )
    base = results[(1, False)][0]
    print(f"speed-up 2 workers vs 1 (no Rerun): {base / results[(2, False)][0]:.2f}x")
    print(f"cost of Rerun output (1 worker):    {results[(1, True)][0] / base:.2f}x the time")
    # Per-session breakdown from the single-worker runs (no contention between sessions).
    for rerun in (False, True):
        records = results[(1, rerun)][1].records
        keys = ["read", "window", "fit", "rrd", "write"]
        means = {k: statistics.mean(r.timings_s.get(k, 0.0) for r in records) for k in keys}
        total = sum(means.values())
        parts = "  ".join(f"{k} {1e3 * v:6.1f} ms" for k, v in means.items())
        print(
            f"per session (1 worker, rerun {'on' if rerun else 'off'}): {parts}  | fit share {means['fit'] / total:.0%}"
        )
    report_overhead = base - sum(sum(r.timings_s.values()) for r in results[(1, False)][1].records)
    print(
        f"batch overhead outside sessions (plan, hashing, report, 1 worker): {report_overhead:.1f} s"
    )
    if not args.keep:
        shutil.rmtree(root, ignore_errors=True)


def _compare_dask(root: Path, inputs: Path, sessions: int, rounds: int) -> None:
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster:
        walls: dict[str, list[float]] = {"processes": [], "dask": []}
        for _ in range(rounds):  # alternate: the machine's load drifts
            walls["processes"].append(_run(root, inputs, 2, False)[0])
            walls["dask"].append(_run(root, inputs, 2, False, cluster.scheduler_address)[0])
    for name, ts in walls.items():
        rates = ", ".join(f"{sessions / t:.1f}" for t in ts)
        print(f"{name:9s} (2 workers, no Rerun): sessions/s per round {rates}")
    ratio = statistics.median(walls["processes"]) / statistics.median(walls["dask"])
    print(f"Dask / local processes throughput: {ratio:.2f}   (target >= 0.90)")


def _warm(package: str) -> None:
    """Import a package's batch stack in a Dask worker (both contenders start warm)."""
    import importlib

    importlib.import_module(f"{package}.batch.runner")


def _versus_ref(ref: str, root: Path, inputs: Path, sessions: int, rounds: int, dask: bool):
    from bench_versus import extract

    where = Path(tempfile.mkdtemp(prefix="wheelcal-ref-"))
    extract(ref, where)
    sys.path.insert(0, str(where))
    # Dask's worker processes are started afresh: they find wheelcal_ref on PYTHONPATH.
    os.environ["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(where), os.environ.get("PYTHONPATH")) if p
    )
    from wheelcal_ref.batch.pipeline import load_pipeline as ref_load
    from wheelcal_ref.batch.runner import run_batch as ref_run

    apis = {"now": (run_batch, load_pipeline), "ref": (ref_run, ref_load)}
    walls: dict[str, list[float]] = {}
    cpus: dict[str, list[float]] = {}

    def rounds_on(cluster_address: str | None) -> None:
        for i in range(rounds):  # alternate, and swap who goes first: the load drifts
            for name in ["now", "ref"] if i % 2 else ["ref", "now"]:
                for mode, address in (("local", None), ("dask", cluster_address)):
                    if mode == "dask" and address is None:
                        continue
                    wall = _run(root, inputs, 2, False, address, apis[name], f"_{name}")[0]
                    walls.setdefault(f"{mode}, {name}", []).append(wall)
                    cpus.setdefault(f"{mode}, {name}", []).append(_run.last_cpu_s)

    if dask:
        from dask.distributed import Client, LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster:
            with Client(cluster.scheduler_address) as client:
                client.run(_warm, "wheelcal")
                client.run(_warm, "wheelcal_ref")
            rounds_on(cluster.scheduler_address)
    else:
        rounds_on(None)
    print(f"versus {ref}: {sessions} sessions, 2 workers, no Rerun, {rounds} alternating rounds")
    for name, ts in walls.items():
        rates = ", ".join(f"{sessions / t:.1f}" for t in ts)
        cpu_ms = 1e3 * statistics.median(cpus[name]) / sessions
        print(
            f"{name:11s}: median {sessions / statistics.median(ts):5.1f} sessions/s ({rates}); "
            f"CPU {cpu_ms:.1f} ms per session (all processes)"
        )
    for what, table in (("throughput", walls), ("CPU-bound throughput", cpus)):
        for mode in ("local", "dask") if dask else ("local",):
            ratio = statistics.median(
                r / n for r, n in zip(table[f"{mode}, ref"], table[f"{mode}, now"], strict=True)
            )
            print(f"{mode}: {what} now / {ref}, median of per-round ratios: {ratio:.3f}")
        if dask:
            for name in ("ref", "now"):
                ratio = statistics.median(
                    local / on_dask
                    for local, on_dask in zip(
                        table[f"local, {name}"], table[f"dask, {name}"], strict=True
                    )
                )
                print(f"{name}: Dask / local {what}, median of per-round ratios: {ratio:.3f}")
    shutil.rmtree(where, ignore_errors=True)


if __name__ == "__main__":
    main()
