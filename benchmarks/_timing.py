"""Shared by the benchmark scripts: repeated timings and their summary line."""

from __future__ import annotations

import statistics
import time


def times(fn, repeats: int, clock=time.perf_counter) -> list[float]:
    """Run ``fn`` once to warm up, then ``repeats`` times; seconds per run."""
    fn()  # warm-up (imports, caches)
    out = []
    for _ in range(repeats):
        t0 = clock()
        fn()
        out.append(clock() - t0)
    return out


def fmt(ts: list[float]) -> str:
    """Median and inter-quartile range in ms."""
    q = statistics.quantiles(ts, n=4) if len(ts) >= 4 else [min(ts), statistics.median(ts), max(ts)]
    med = 1e3 * statistics.median(ts)
    return f"median {med:8.1f} ms   (IQR {1e3 * q[0]:.1f}–{1e3 * q[2]:.1f} ms, n={len(ts)})"


def interleaved_times(fns: dict, repeats: int, clock=time.perf_counter) -> dict[str, list[float]]:
    """Like :func:`times` for several functions, run in turn each round.

    On a shared machine the load drifts within seconds: alternating the
    contenders makes their ratio far steadier than timing one after the other.
    """
    for fn in fns.values():
        fn()  # warm-up
    out: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(repeats):
        for name, fn in fns.items():
            t0 = clock()
            fn()
            out[name].append(clock() - t0)
    return out
